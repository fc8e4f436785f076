"""Figures are reproducible: the same figure gives the same SVG bytes in every run (no random
id salt, no date), and different figures inlined in one report get different hashed ids."""

from __future__ import annotations

import re

import numpy as np

from aatest.presentation.figures import new_figure, to_svg

#: ids matplotlib derives from its salt (clip paths, marker definitions); the sequential ones
#: (``line2d_1``…) are the same in every figure whatever the salt
_HASHED_ID = re.compile(r'id="([mp][0-9a-f]{10})"')


def _figure(gain: float) -> object:
    fig, ax = new_figure(2)
    ax[0, 0].plot(np.arange(10.0), gain * np.arange(10.0), "o", ms=3)
    ax[0, 0].set(title="gain", ylabel="V")
    ax[1, 0].semilogx(np.arange(1.0, 10.0), np.sqrt(np.arange(1.0, 10.0)))
    fig.tight_layout()
    return fig


def test_the_same_figure_renders_to_the_same_bytes() -> None:
    first, again = to_svg(_figure(1.0)), to_svg(_figure(1.0))
    assert first == again
    assert "<dc:date>" not in first


def test_different_figures_get_different_hashed_ids() -> None:
    one, other = to_svg(_figure(1.0)), to_svg(_figure(2.0))
    ids_one, ids_other = set(_HASHED_ID.findall(one)), set(_HASHED_ID.findall(other))
    assert ids_one and ids_other
    assert not ids_one & ids_other
