"""The Bode figure drawn on a reused figure is the very SVG of a new figure.

Why exact equality: the reuse only skips rebuilding what every drawing rebuilds the same way
(axes, ticks, measured labels, the frequency axes' extents); a changed byte would mean state
left from the previous group (limits, layout, ticks) shows in the next one. The layout leaves
the spines out (their extents lie inside the axes' and their labels'): the reference does too,
and its subplot parameters are those of matplotlib's own layout to rounding.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from aatest.plugins.analysis import tf_bode
from aatest.plugins.analysis.tf_bode import MODEL_GRID_HZ, bode_svg
from aatest.plugins.analysis.tfest import DiscreteTf
from aatest.presentation.figures import frequency_axis, new_figure, to_svg

DT_S = 1 / 2000.0


def _new_figure(f: np.ndarray, h: np.ndarray, model: DiscreteTf, title: str,
                spines_in_layout: bool = False) -> Any:
    """The drawing on a new figure each time (the former one, kept as the reference)."""
    fig, ax = new_figure(2, height_in=2.4)
    resp = model.response(MODEL_GRID_HZ)
    ax[0, 0].semilogx(f, 20 * np.log10(np.abs(h)), "o", ms=3, label="FRF")
    ax[0, 0].semilogx(MODEL_GRID_HZ, 20 * np.log10(np.abs(resp)), "-", lw=0.8, label="model")
    ax[1, 0].semilogx(f, np.degrees(np.unwrap(np.angle(h))), "o", ms=3)
    ax[1, 0].semilogx(MODEL_GRID_HZ, np.degrees(np.unwrap(np.angle(resp))), "-", lw=0.8)
    ax[0, 0].set(ylabel="gain / dB", title=title)
    ax[1, 0].set(xlabel="frequency / Hz", ylabel="phase / °")
    ax[0, 0].legend(fontsize=6)
    frequency_axis(ax[0, 0], ax[1, 0])
    for spine in (*ax[0, 0].spines.values(), *ax[1, 0].spines.values()):
        spine.set_in_layout(spines_in_layout)
    fig.tight_layout()
    return fig


def _new_figure_svg(f: np.ndarray, h: np.ndarray, model: DiscreteTf, title: str) -> str:
    return to_svg(_new_figure(f, h, model, title))


def _cases() -> list[tuple[np.ndarray, np.ndarray, DiscreteTf, str]]:
    """Groups of different bands, gains (tick label widths) and models, one after another."""
    rng = np.random.default_rng(5)
    models = [DiscreteTf(np.array([0.01, 0.002]), np.array([1.0, -1.9, 0.905]), 25, DT_S),
              DiscreteTf(np.array([3.0]), np.array([1.0, -0.97]), 3, DT_S),
              DiscreteTf(np.array([1e-4, 2e-4, 1e-4]), np.array([1.0, -1.95, 0.951]), 0, DT_S)]
    bands = [(0.4, 9.0, 28), (1.0, 28.0, 24), (0.5, 3.0, 7)]  # (lowest Hz, highest Hz, points)
    cases = []
    for k, j in ((0, 0), (0, 1), (1, 2), (2, 1), (2, 0)):
        f = np.geomspace(*bands[k][:2], bands[k][2])
        h = models[j].response(f) * (1 + 0.01 * rng.normal(size=f.size)) * 10.0 ** (2 * k - 2)
        cases.append((f, h, models[j], f"v_sz case {k} n={j}"))
    return cases


def test_reused_figure_gives_the_bytes_of_a_new_one() -> None:
    for f, h, model, title in _cases():
        assert bode_svg(f, h, model, title) == _new_figure_svg(f, h, model, title), title


#: ulps of a display coordinate by which a spine's edge may differ from the axes' edge it
#: coincides with (it is reached through another chain of transforms: a bbox, one affine
#: transform, the union with the tick labels' boxes, the layout's subtraction); generous
_SPINE_EDGE_ULPS = 8


def _spine_rounding(fig: Any) -> float:
    """How far leaving the spines out may move a subplot parameter, from the figure's sizes.

    A margin is measured in display pixels and divided by the figure's size, so an edge off
    by k ulps of the largest coordinate (≈ the figure's size in px) moves left/right/bottom/
    top by ≈ k·eps; wspace/hspace divide a gap by the mean axes size, which scales that by
    (figure px ÷ smallest axes px). The bound is the latter, for every parameter.
    """
    figure_px = max(fig.bbox.width, fig.bbox.height)
    axes_px = min(min(ax.bbox.width, ax.bbox.height) for ax in fig.axes)
    return _SPINE_EDGE_ULPS * float(np.finfo(float).eps) * figure_px / axes_px


def test_layout_is_matplotlibs_with_the_spines_to_rounding() -> None:
    keys = ("left", "right", "bottom", "top", "wspace", "hspace")
    for f, h, model, title in _cases():
        bode_svg(f, h, model, title)
        mine = tf_bode._FIGURES.bode.fig.subplotpars
        theirs_fig = _new_figure(f, h, model, title, spines_in_layout=True)
        theirs, bound = theirs_fig.subplotpars, _spine_rounding(theirs_fig)
        for key in keys:
            assert abs(getattr(mine, key) - getattr(theirs, key)) <= bound, (title, key)


def test_frequency_axes_are_measured_once_per_view() -> None:
    for f, h, model, title in _cases():
        bode_svg(f, h, model, title)
    figure = tf_bode._FIGURES.bode
    # every case shows 0.1-500 Hz (the model's grid): one extent per axis and kind of call
    assert len(figure.x_extents) == len({(k[0], k[-1]) for k in figure.x_extents}) <= 4
    assert "get_tightbbox" not in vars(figure.gain.xaxis)  # the axis's own method again


def test_a_wider_band_is_measured_anew() -> None:
    f, h, model, title = _cases()[1]
    wide = np.geomspace(20.0, 900.0, 12)  # beyond the model's grid: other frequency limits
    for case in ((wide, model.response(wide), model, "wide"), (f, h, model, title)):
        assert bode_svg(*case) == _new_figure_svg(*case), case[-1]
