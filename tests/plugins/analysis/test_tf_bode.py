"""The Bode figure drawn on a reused figure is the very SVG of a new figure.

Why exact equality: the reuse only skips rebuilding what every drawing rebuilds the same way
(axes, ticks, measured labels); a changed byte would mean state left from the previous group
(limits, layout, ticks) shows in the next one.
"""

from __future__ import annotations

import numpy as np

from aatest.plugins.analysis.tf_bode import MODEL_GRID_HZ, bode_svg
from aatest.plugins.analysis.tfest import DiscreteTf
from aatest.presentation.figures import frequency_axis, new_figure, to_svg

DT_S = 1 / 2000.0


def _new_figure_svg(f: np.ndarray, h: np.ndarray, model: DiscreteTf, title: str) -> str:
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
    fig.tight_layout()
    return to_svg(fig)


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
