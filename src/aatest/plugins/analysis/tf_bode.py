"""The Bode figure of a fitted transfer function: the FRF points and the model to 500 Hz.

Every group of the stepped sine gets one, drawn on the transfer-function analysis's workers.
The figure is built once per thread and redrawn with each group's data (lines, title, limits,
layout): the same SVG bytes as a new figure (tests/plugins/analysis/test_tf_bode.py) at
≈ 60 % of its CPU (0.23 → 0.14 s a figure; 0.09 s with the layout of
:func:`~aatest.presentation.figures.tight_layout`) — a new figure creates its ≈ 100 ticks
(each a handful of artists) and measures every tick label again, for the same axes each
time. The figure stays with its thread (≈ 3 MB with matplotlib's caches). Its layout measures
the frequency axes once per view and leaves the spines out (:meth:`_BodeFigure._layout`):
0.46 → 0.35 s of CPU for the stepped sine's five figures in one process, the layout's
subplot parameters those of matplotlib's own to an ulp.
"""

from __future__ import annotations

import threading
from typing import Any

import numpy as np

from aatest.plugins.analysis.tfest import DiscreteTf
from aatest.presentation.figures import frequency_axis, new_figure, tight_layout, to_svg

#: the model's frequency grid, Hz (0.1–500 Hz: extrapolated beyond the measured band)
MODEL_GRID_HZ = np.logspace(-1, np.log10(500.0), 300)


class _BodeFigure:
    """Two stacked axes (gain, phase) with the FRF points and the model's curves."""

    def __init__(self) -> None:
        self.fig, ax = new_figure(2, height_in=2.4)
        self.gain, self.phase = ax[0, 0], ax[1, 0]
        #: subplot parameters of a new figure: each drawing's layout starts from them
        self.start = {k: getattr(self.fig.subplotpars, k)
                      for k in ("left", "right", "bottom", "top", "wspace", "hspace")}
        nan = np.array([np.nan])
        self.lines = [self.gain.semilogx(nan, nan, "o", ms=3, label="FRF")[0],
                      self.gain.semilogx(nan, nan, "-", lw=0.8, label="model")[0],
                      self.phase.semilogx(nan, nan, "o", ms=3)[0],
                      self.phase.semilogx(nan, nan, "-", lw=0.8)[0]]
        self.gain.set(ylabel="gain / dB")
        self.phase.set(xlabel="frequency / Hz", ylabel="phase / °")
        self.gain.legend(fontsize=6)
        frequency_axis(self.gain, self.phase)
        # the spines' extents (the axes' edges and the tick marks) lie inside those of the axes
        # and their tick labels, so the layout is the same without them; measuring them
        # updated every tick of their axis again (≈ 10 % of a figure's CPU)
        for ax in (self.gain, self.phase):
            for spine in ax.spines.values():
                spine.set_in_layout(False)
        #: the frequency axes' extents by what they depend on (see :meth:`_layout`)
        self.x_extents: dict[tuple[Any, ...], Any] = {}

    def _layout(self) -> None:
        """:func:`tight_layout`, each frequency axis measured once per view and position.

        Why: a frequency axis shows the same ticks and labels whenever its limits are the same
        (the model's grid sets them: 0.1–500 Hz for every group), and the layout measures it
        at the same start position each time; its extent (≈ 40 ticks and their labels
        updated and measured) is then the same box, kept instead of measured again. The gain
        and phase axes, which differ per group, are measured each time.
        """
        measured = []
        for ax in (self.gain, self.phase):
            axis, real = ax.xaxis, ax.xaxis.get_tightbbox

            def kept(renderer: Any = None, *, for_layout_only: bool = False, ax: Any = ax,
                     real: Any = real) -> Any:
                key = (id(ax), ax.get_xlim(), ax.bbox.bounds, self.fig.dpi, for_layout_only)
                if key not in self.x_extents:
                    self.x_extents[key] = real(renderer, for_layout_only=for_layout_only)
                return self.x_extents[key]

            axis.get_tightbbox = kept
            measured.append(axis)
        try:
            tight_layout(self.fig)
        finally:
            for axis in measured:
                del axis.get_tightbbox  # the class's own again

    def svg(self, curves: list[tuple[np.ndarray, np.ndarray]], title: str) -> str:
        for line, (x, y) in zip(self.lines, curves, strict=True):
            line.set_data(x, y)
        self.gain.set_title(title)
        self.fig.subplots_adjust(**self.start)
        for ax in (self.gain, self.phase):
            ax.relim()
            ax.autoscale_view()
        self._layout()
        return to_svg(self.fig)


_FIGURES = threading.local()


def bode_svg(f_hz: np.ndarray, h: np.ndarray, model: DiscreteTf, title: str) -> str:
    """SVG of the gain (dB) and phase (°) of the FRF points ``h`` at ``f_hz`` and of
    ``model`` on :data:`MODEL_GRID_HZ`."""
    resp = model.response(MODEL_GRID_HZ)
    curves = [(f_hz, 20 * np.log10(np.abs(h))), (MODEL_GRID_HZ, 20 * np.log10(np.abs(resp))),
              (f_hz, np.degrees(np.unwrap(np.angle(h)))),
              (MODEL_GRID_HZ, np.degrees(np.unwrap(np.angle(resp))))]
    figure: Any = getattr(_FIGURES, "bode", None)
    if figure is None:
        figure = _FIGURES.bode = _BodeFigure()
    return str(figure.svg(curves, title))
