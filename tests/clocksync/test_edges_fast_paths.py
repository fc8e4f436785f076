"""Edge pairing's fast paths pair exactly as the plain formulation did.

The run checks every recorded step's clock relation and the analysis fits it again with the
same code, so a faster pairing must give the very same pairs (bit for bit): it performs the
same IEEE operations on the same operands (a slice instead of a mask for time-ordered edges,
each distance measured once, the median's order statistics from a sort instead of a
partition), so equality, not a tolerance, is the right check.
"""

from __future__ import annotations

import numpy as np
import pytest

from aatest.clocksync import edges
from aatest.engine.errors import AnalysisError

PERIOD_S = 0.01
TABLE_DT_S = 1.0 / 2000.0


def _reference_match(t_table: np.ndarray, t_pred: np.ndarray, tol_s: float
                     ) -> tuple[np.ndarray, np.ndarray]:
    k = np.clip(np.searchsorted(t_pred, t_table), 1, t_pred.size - 1)
    k = np.where(np.abs(t_pred[k - 1] - t_table) < np.abs(t_pred[k] - t_table), k - 1, k)
    return np.abs(t_pred[k] - t_table) < tol_s, k


def _reference_robust(tt: np.ndarray, td: np.ndarray, floor_s: float
                      ) -> tuple[np.ndarray, np.ndarray]:
    coef, res = edges.line_fit(tt, td)
    mad = 1.4826 * float(np.median(np.abs(res - np.median(res))))
    keep = np.abs(res) <= max(5.0 * mad, floor_s)
    if keep.sum() >= edges.MIN_EDGES and not keep.all():
        coef, _ = edges.line_fit(tt[keep], td[keep])
        coef = np.array([coef[0] - coef[1] * (td[keep][0] - td[0]), coef[1]])
    return coef, keep


def _reference_pairs(t_table: np.ndarray, t_daq: np.ndarray, offset0: float | None
                     ) -> tuple[np.ndarray, np.ndarray]:
    """``pair_edges`` as first written: a mask per window, np.median, distances twice."""
    tol_s = edges.PAIR_TOLERANCE_PERIODS * PERIOD_S
    coef = np.array([t_daq[0] + (t_table[0] - t_daq[0] if offset0 is None else offset0), 1.0])
    window_s = edges.FIRST_WINDOW_S
    while True:
        sel = t_table <= t_table[0] + window_s
        ok, k = _reference_match(t_table[sel], coef[0] + coef[1] * (t_daq - t_daq[0]), tol_s)
        if ok.sum() < edges.MIN_EDGES or np.unique(k[ok]).size != k[ok].size:
            raise AnalysisError("cannot pair edges")
        tt, td = t_table[sel][ok], t_daq[k[ok]]
        fit, keep = _reference_robust(tt, td, 1.5 * TABLE_DT_S)
        coef = np.array([fit[0] - fit[1] * (td[0] - t_daq[0]), fit[1]])
        if sel.all():
            return tt[keep], td[keep]
        window_s *= 2.0


def _edges(seed: int, n: int, drift_ppm: float) -> tuple[np.ndarray, np.ndarray]:
    """(table, DAQ) edge times of a 100 Hz pulse: DAQ edges on its 2 kHz samples, table edges
    latch-corrected with 3 µs jitter, a few 2 ms outliers and a gap of 30 missing edges."""
    rng = np.random.default_rng(seed)
    t_daq = np.round(np.arange(n) * PERIOD_S / TABLE_DT_S) * TABLE_DT_S + 0.3
    t_table = 12.0 + t_daq * (1.0 + drift_ppm * 1e-6) + 3e-6 * rng.standard_normal(n)
    t_table[rng.choice(n, 5, replace=False)] += 2e-3
    return np.delete(t_table, np.s_[n // 3: n // 3 + 30]), t_daq


@pytest.mark.parametrize(("seed", "n", "drift_ppm", "offset"),
                         [(0, 6554, 40.0, True), (1, 6554, -120.0, False), (2, 350, 5.0, True)])
def test_pairing_equals_the_masked_pairing(seed: int, n: int, drift_ppm: float,
                                           offset: bool) -> None:
    t_table, t_daq = _edges(seed, n, drift_ppm)
    offset0 = 12.0 + 0.3 * drift_ppm * 1e-6 if offset else None
    fast = edges.pair_edges("s", t_table, t_daq, PERIOD_S, offset0, TABLE_DT_S)
    plain_table, plain_daq = _reference_pairs(t_table, t_daq, offset0)
    assert fast.t_table.size > 0.9 * t_table.size
    assert np.array_equal(fast.t_table, plain_table)
    assert np.array_equal(fast.t_daq, plain_daq)


@pytest.mark.parametrize(("head", "drift_ppm"), [(0.6, 40.0), (0.05, -90.0)])
def test_a_table_log_shorter_than_the_daq_record_pairs_as_the_masked_pairing(
        head: float, drift_ppm: float) -> None:
    """The last windows then reach DAQ edges no table edge pairs with."""
    t_table, t_daq = _edges(4, 6554, drift_ppm)
    t_table = t_table[:int(head * t_table.size)]
    fast = edges.pair_edges("s", t_table, t_daq, PERIOD_S, None, TABLE_DT_S)
    plain_table, plain_daq = _reference_pairs(t_table, t_daq, None)
    assert fast.t_table.size > 0.9 * t_table.size
    assert np.array_equal(fast.t_table, plain_table)
    assert np.array_equal(fast.t_daq, plain_daq)


def test_unordered_edges_pair_as_the_masked_pairing() -> None:
    t_table, t_daq = _edges(3, 2000, 10.0)
    t_table[[100, 101]] = t_table[[101, 100]]  # two edges out of time order
    fast = edges.pair_edges("s", t_table, t_daq, PERIOD_S, None, TABLE_DT_S)
    plain_table, plain_daq = _reference_pairs(t_table, t_daq, None)
    assert np.array_equal(fast.t_table, plain_table)
    assert np.array_equal(fast.t_daq, plain_daq)


@pytest.mark.parametrize("size", [1, 2, 3, 10, 6553, 6554])
def test_median_is_numpys_median(size: int) -> None:
    rng = np.random.default_rng(size)
    values = np.round(rng.standard_normal(size) * 1e-6, 12)  # with repeated values
    values[: size // 4] = 0.0
    assert edges._median(values) == float(np.median(values))


def test_median_with_nan_is_numpys_nan() -> None:
    assert np.isnan(edges._median(np.array([1.0, np.nan, 3.0, 2.0])))
