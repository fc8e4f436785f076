"""The one way a figure becomes SVG: every plot of aatest goes through :func:`to_svg`.

Analyses, the report, the diagnosis, the fleet pages and ``history`` all draw with
matplotlib's object API (:func:`new_figure`: no pyplot state, safe in the station's worker
threads) and render here, so every SVG is reproducible: the same figure gives the same bytes
in every run. Matplotlib would otherwise salt its element ids at random (``svg.hashsalt``)
and stamp the date; here the salt is a digest of what the figure shows
(:func:`content_salt`), so two different figures inlined in one page still get different
ids, and the date is left out. Text stays text (``svg.fonttype: none``: smaller, searchable).
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib
import io
from collections.abc import Callable, Iterator, Mapping
from typing import TYPE_CHECKING, Any, TypeAlias

import numpy as np

from aatest.parallel import aside

if TYPE_CHECKING:
    from matplotlib.figure import Figure

#: applied while a figure is drawn (never globally: plugins draw with matplotlib too)
STYLE: dict[Any, Any] = {"svg.fonttype": "none", "font.size": 9}


#: a figure being drawn (:func:`drawn`): its SVG is its ``result()``
Drawing: TypeAlias = aside.Later[str]


def warm() -> None:
    """Make ready what every figure needs: matplotlib's ``Figure`` and SVG backend imported,
    its fonts found and loaded (the first text drawn). ≈ 0.35 s of CPU, made by the first
    process that draws aside before it forks the others (:func:`drawing_aside`), where each
    process paid ≈ 0.1 s of it at its first figure. Only caches are filled: a figure's SVG
    is the same bytes drawn after this or in a fresh process."""
    for module in ("matplotlib.figure", "matplotlib.backends.backend_svg"):
        importlib.import_module(module)
    fig, ax = new_figure()
    ax[0, 0].set(title="warm", xlabel="x", ylabel="y")
    to_svg(fig)


def drawing_aside() -> contextlib.AbstractContextManager[None]:
    """Figures :func:`drawn` inside the block are drawn aside (:mod:`aatest.parallel.aside`:
    forked processes that import matplotlib first), and taken by the block's end."""
    return aside.running(warm)


def ready_to_draw() -> None:
    """Start the open :func:`drawing_aside` block's processes now, so they import matplotlib
    (:func:`warm`) while this process goes on: a run starts them as its record phase ends,
    once the step files are merged (:func:`aatest.engine.run.session.finish_recording`)."""
    aside.ahead()


def drawn(draw: Callable[..., str], *args: Any) -> Drawing:
    """``draw(*args)``'s SVG, drawn aside while one draws (:func:`drawing_aside`), else now.

    ``draw`` is a module-level function and ``args`` plain data (they are pickled); the
    SVG is the same bytes wherever it is drawn.
    """
    return aside.submit(draw, *args)


class DrawnFigures(Mapping[str, str]):
    """Figures by name, each SVG taken when it is first read: an analysis returns these
    (``AnalysisOutput.figures``) while they are drawn aside, and the results take them when
    they are written."""

    def __init__(self, figures: Mapping[str, str | Drawing]) -> None:
        self._figures = dict(figures)

    def __getitem__(self, name: str) -> str:
        figure = self._figures[name]
        return figure if isinstance(figure, str) else figure.result()

    def __iter__(self) -> Iterator[str]:
        return iter(self._figures)

    def __len__(self) -> int:
        return len(self._figures)


def new_figure(rows: int = 1, width_in: float = 6.0, height_in: float = 3.0) -> tuple[Any, Any]:
    """A small figure with ``rows`` stacked axes, without pyplot's global state (Agg-safe).

    Matplotlib is imported here, not with this module: importing it builds its font cache
    in the user's home, and commands that draw nothing (``aatest validate``) leave no file.
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_in, height_in * rows))
    return fig, fig.subplots(rows, 1, squeeze=False)


def frequency_axis(*axes: Any) -> None:
    """Log frequency axes whose decades are labelled as plain numbers (0.1, 1, 10, 100 Hz).

    Why: matplotlib labels log decades in mathtext (10⁻¹, 10⁰, …), which every renderer parses
    anew with pyparsing, twice per figure (the layout's Agg pass and the SVG): measured, ≈ 30 %
    of a Bode figure's rendering time, for labels a reader takes in faster as numbers. Minor
    ticks keep matplotlib's own labels (shown only on an axis spanning about a decade or less).
    """
    from matplotlib.ticker import StrMethodFormatter  # lazily: validate imports no matplotlib

    for ax in axes:
        ax.set_xscale("log")
        ax.xaxis.set_major_formatter(StrMethodFormatter("{x:g}"))


def tight_layout(fig: Figure) -> None:
    """Adjust ``fig``'s subplot parameters as :meth:`Figure.tight_layout` does, leaving it
    without a layout engine.

    Why: ``Figure.tight_layout`` leaves a placeholder engine on the figure, and a figure with
    any engine is drawn twice by ``savefig`` (a layout pass, then the file); measured, the
    extra pass is 15–40 % of a two-axes Bode figure's ``savefig``. The same subplot
    parameters, the same SVG bytes (tests/plugins/analysis/test_tf_bode.py).
    """
    from matplotlib.layout_engine import TightLayoutEngine

    if fig.get_layout_engine() is not None:  # e.g. constrained layout set in matplotlibrc
        fig.tight_layout()
        return
    # Figure.tight_layout's own engine: its defaults, and no ``rect`` (the engine's default
    # rect (0, 0, 1, 1) would run the layout a second time, to the same parameters); the
    # stubs type ``rect`` as a tuple, but None is what Figure.tight_layout itself passes
    no_rect: Any = None
    TightLayoutEngine(pad=1.08, h_pad=None, w_pad=None, rect=no_rect).execute(fig)


def content_salt(fig: Figure) -> str:
    """A digest of what a figure shows: its axes' texts and the data of their lines and
    collections (the salt of its SVG element ids)."""
    digest = hashlib.sha256()
    for ax in fig.axes:
        for text in (ax.get_title(), ax.get_xlabel(), ax.get_ylabel()):
            digest.update(text.encode() + b"\0")
        for line in ax.lines:
            digest.update(np.ascontiguousarray(line.get_xydata(), dtype=np.float64).tobytes())
        for collection in ax.collections:
            digest.update(np.ascontiguousarray(collection.get_offsets(), dtype=np.float64)
                          .tobytes())
    return digest.hexdigest()[:16]


def to_svg(fig: Figure, *, tight: bool = False, inline: bool = False) -> str:
    """Render ``fig`` to an SVG string with reproducible element ids and no date.

    Parameters
    ----------
    fig
        The figure (from :func:`new_figure` or :class:`matplotlib.figure.Figure`).
    tight
        Crop to the drawn content (``bbox_inches="tight"``), as the fleet and history pages do.
    inline
        Drop the XML prolog and doctype, for SVG inlined in an HTML page.
    """
    import matplotlib

    buffer = io.StringIO()
    with matplotlib.rc_context({"svg.fonttype": "none", "svg.hashsalt": content_salt(fig)}):
        fig.savefig(buffer, format="svg", metadata={"Date": None},
                    bbox_inches="tight" if tight else None)
    text = buffer.getvalue()
    return text[text.index("<svg"):] if inline else text
