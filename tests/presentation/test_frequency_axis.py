"""Log frequency axes label their decades as plain numbers, not as mathtext powers of ten."""

from __future__ import annotations

import numpy as np

from aatest.presentation.figures import frequency_axis, new_figure, to_svg


def test_decades_are_labelled_as_plain_numbers() -> None:
    fig, ax = new_figure(1)
    ax[0, 0].plot(np.logspace(-1, np.log10(500.0), 50), np.arange(50.0))
    frequency_axis(ax[0, 0])
    svg = to_svg(fig)  # draws: the tick labels are set now
    labels = [t.get_text() for t in ax[0, 0].get_xticklabels() if t.get_text()]
    assert ax[0, 0].get_xscale() == "log"
    assert {"0.1", "1", "10", "100"} <= set(labels)
    assert not any("$" in label for label in labels)  # no mathtext to parse
    assert ">100<" in svg
