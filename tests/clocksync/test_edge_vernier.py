"""The latch-less edge fit reads the vernier of clocks that are not commensurate.

Without latch times an edge is known only to the table sample that registered it; the fit is
the set of lines through every edge's interval (:func:`aatest.clocksync.edges.interval_fit`).
Where the pulse period is a whole number of table samples (the twin's 100 Hz pulse on a 2 kHz
table: 20 samples), the edges' position in their sample moves only by drift × 20 samples per
edge, so over a record they cross ⌊|drift|·T/dt⌋ samples and a small drift is only bounded.
Where it is not (here 10.0137 ms: 20.0274 samples), the edges take every position in their
sample and the same feasible set fixes the drift to a few times the edge-jitter allowance over
the record — no separate vernier estimator is needed. (A small rational ratio gives a coarse
vernier only: 10.1 ms = 101/5 samples reads positions 0.2 sample apart.) The allowance (12 µs,
four times the twin's edge jitter) sets the floor: ≈ 8.5 ppm wide over 8 s, a uniform u of ≈
2.5 ppm — about what a least-squares line through 800 quantised edges would give. Synthetic
edges from a known line; no noise beyond the registration's quantisation, so the truth must lie
inside the feasible set.
"""

from __future__ import annotations

import numpy as np
import pytest

from aatest.clocksync.edges import JITTER_ALLOWANCE_S, LAG_SAMPLES, interval_fit

TABLE_DT_S = 5e-4
RECORD_S = 8.0


def _registered(period_s: float, drift_ppm: float, offset_s: float) -> tuple[np.ndarray, ...]:
    """(registering table rows' times, DAQ edge times) of a pulse of ``period_s`` (DAQ s)."""
    t_daq = np.arange(0.0, RECORD_S, period_s) + 0.0025
    t_table = offset_s + t_daq * (1.0 + drift_ppm * 1e-6)
    # registered on the row after the first row at or after the edge (docs/method.md §2)
    rows = np.ceil(t_table / TABLE_DT_S - 1e-9) + 1.0
    assert LAG_SAMPLES == (1.0, 2.0)
    return rows * TABLE_DT_S, t_daq


def _range_ppm(period_s: float, drift_ppm: float) -> tuple[float, float]:
    registered, t_daq = _registered(period_s, drift_ppm, 1.23e-4)
    fit = interval_fit("s", registered, t_daq, TABLE_DT_S)
    return (fit.slope_range[0] - 1.0) * 1e6, (fit.slope_range[1] - 1.0) * 1e6


@pytest.mark.parametrize("drift_ppm", [4.7, -26.3, 61.0])
def test_incommensurate_pulse_fixes_a_small_drift(drift_ppm: float) -> None:
    lo, hi = _range_ppm(10.0137e-3, drift_ppm)
    assert lo <= drift_ppm <= hi
    # the extreme lines pivot within the allowance at both ends: ≈ 4 × 12 µs over 8 s = 6 ppm
    # (measured 8.4–8.7 ppm: the positions are dense but discrete); twice that bounds it
    assert hi - lo < 2.0 * 4.0 * JITTER_ALLOWANCE_S / RECORD_S * 1e6


@pytest.mark.parametrize("drift_ppm", [4.7, -26.3])
def test_commensurate_pulse_only_bounds_it(drift_ppm: float) -> None:
    """The twin's case: fewer than two crossings (|drift|·T/dt < 1) leave tens of ppm."""
    lo, hi = _range_ppm(10.0e-3, drift_ppm)
    assert lo <= drift_ppm <= hi
    assert hi - lo > 20.0
