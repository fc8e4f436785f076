"""The rotor's stiction gap on the study's 10 °/s² stepped sine (issue 28, bench/study_lowamp.py).

Short coherent records (2^14 samples, 8 s) at 0.98, 2.93 and 10.01 Hz on the realistic rig with
and without the gap, through the FRF analysis. The study: at 10 °/s² the gain starts to fall
at ≈ 2 Hz and is 0.5 dB down at 10 Hz. A damping's roll-off grows as f²: the loss at 2.93 Hz is
(2.93² − 0.98²)/(10.01² − 0.98²) = 0.077 of the loss at 10 Hz; the gap's grows linearly with
f/A, up to (2.93 − 0.98)/(10.01 − 0.98) = 0.22 of it, mixed with the dynamics' f² share. At
10 °/s² the output noise costs ≈ 0.002 dB of gain per point (1 mV on 40 mV over 8–80 cycles),
≈ 0.01 of the ratios below. Four 8 s records per rig: ≈ 60 s on a loaded machine (slow).
"""

from __future__ import annotations

import pytest
from twin_steps import sine_step

from aatest.engine.analysis.passes import run_analysis
from aatest.twin.api import realistic_rig_model, simulate_dataset


def _loss_db(stiction: bool) -> dict[float, float]:
    """Gain below the 0.98 Hz point (dB) at 2.93 and 10.01 Hz, 10 °/s², seed 7."""
    steps = [sine_step(f, 10.0, samples=2**14, id=f"f{f}") for f in (0.977, 2.93, 10.01)]
    data = simulate_dataset(realistic_rig_model(stiction=stiction), steps, 7)
    points = sorted(run_analysis("frf", data).result["v_sz"], key=lambda p: p.frequency_hz)
    flat = points[0].gain_db
    return {round(p.frequency_hz, 1): flat - p.gain_db for p in points[1:]}


@pytest.mark.slow
def test_the_gap_makes_the_10_dps2_gain_fall_linearly_in_f() -> None:
    plain, gap = _loss_db(False), _loss_db(True)
    # damping: at most the f² share (measured 0.046: the other terms, e.g. hysteresis, add a
    # little at every frequency and pull the 0.98 Hz reference with the rest)
    assert plain[2.9] / plain[10.0] < 0.1, plain
    assert gap[2.9] / gap[10.0] > 0.12, gap  # the gap's linear share
    # and the 10 Hz roll-off stays the study's 0.5 dB within the bench's ± 0.15 dB
    assert gap[10.0] == pytest.approx(0.5, abs=0.15)
