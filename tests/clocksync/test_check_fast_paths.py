"""The run-time check's fast paths give the relation the plain computation gave, bit for bit.

``clock_relation`` is the run's check of every step and the relation the early child takes
instead of fitting it again, so its fast paths (the robust line's medians skipped when every
residual is inside the floor, the last window's line reused, the DAQ time base read at the
edges only, one comparison for the rising edges) must perform the same IEEE operations on the
same operands: equality, not a tolerance, and the same error where the plain path raised.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from synthetic_rig import SynthRig, make_step, sine_step
from test_edges_fast_paths import _reference_robust

from aatest.clocksync import clock_fit, edges, freeze_pulse
from aatest.clocksync.relation import ClockRelation
from aatest.engine.errors import AnalysisError
from aatest.engine.logs import SampledLog
from aatest.recording.dataset import StepData


@pytest.mark.parametrize("case", ["inside-floor", "outliers", "wide-scatter", "nan"])
def test_robust_line_equals_the_plain_one(case: str) -> None:
    rng = np.random.default_rng(7)
    td = np.arange(500) * 0.01
    tt = 3.0 + td * (1 + 40e-6) + 3e-6 * rng.standard_normal(td.size)
    floor_s = 0.75e-3
    if case == "outliers":
        tt[[10, 200]] += 2e-3
    elif case == "wide-scatter":  # beyond the floor, inside five deviations: all kept
        tt += 1e-3 * rng.standard_normal(td.size)
    elif case == "nan":
        tt[50] = np.nan
    coef, keep, res = edges._robust_line(tt, td, floor_s)
    ref_coef, ref_keep = _reference_robust(tt, td, floor_s)
    assert np.array_equal(coef, ref_coef, equal_nan=True)
    assert np.array_equal(keep, ref_keep)
    if res is not None:  # the residuals handed on are those of the line handed on
        assert keep.all()
        assert np.array_equal(res, edges.line_fit(tt, td)[1])


@pytest.mark.parametrize("outliers", [False, True])
def test_paired_fit_is_the_line_fit_of_the_pairs(outliers: bool) -> None:
    rng = np.random.default_rng(3)
    t_daq = np.round(np.arange(3000) * 20.0) / 2000.0 + 0.3
    t_table = 12.0 + t_daq * (1 + 80e-6) + 3e-6 * rng.standard_normal(t_daq.size)
    if outliers:
        t_table[[5, 1500]] += 2e-3
    pairs = edges.pair_edges("s", t_table, t_daq, 0.01, None, 1 / 2000)
    assert (pairs.fit is None) == outliers
    if pairs.fit is not None:
        coef, res = edges.line_fit(pairs.t_table, pairs.t_daq)
        assert np.array_equal(pairs.fit[0], coef)
        assert np.array_equal(pairs.fit[1], res)


def _reference_relation(data: StepData) -> ClockRelation:
    """``clock_relation`` as it was: the whole regular DAQ time base, a plain line fit."""
    time_s = np.asarray(data.daq.time_s, dtype=np.float64)
    fit = clock_fit.regular_fit(time_s)
    daq_time_s = clock_fit.regular_time(time_s, fit)
    t_daq, offset0 = clock_fit.daq_edges(data, daq_time_s)
    relation = clock_fit.edge_relation(data.step.id, data.table,
                                       float(data.daq.sample_rate_hz), t_daq, offset0)
    relation = replace(relation, record_span_daq_s=(float(daq_time_s[0]),
                                                    float(daq_time_s[-1])))
    freeze_pulse._relation(data, daq_time_s, relation)
    return replace(relation, daq_time_fit=fit)


def _plain_pair_edges(*args, **kwargs):  # type: ignore[no-untyped-def]
    """``pair_edges`` without the last window's line handed on (fit again as before)."""
    pairs = _pair_edges(*args, **kwargs)
    return edges.Paired(pairs.t_table.copy(), pairs.t_daq.copy())


_pair_edges = edges.pair_edges


def _no_trigger(data: StepData) -> StepData:
    ch = {k: v for k, v in data.daq.channels.items() if k != "trigger"}
    return replace(data, daq=SampledLog("daq", data.daq.sample_rate_hz, data.daq.time_s, ch))


def _half_latched(data: StepData) -> StepData:
    ch = dict(data.table.channels)
    if "fp_latch_s" not in ch:
        return data
    latch = np.array(ch["fp_latch_s"], dtype=np.float64)
    latch[: latch.size * 3 // 5] = np.nan
    ch["fp_latch_s"] = latch
    return replace(data, table=SampledLog("table", 2000.0, data.table.time_s, ch))


def _short(data: StepData) -> StepData:
    n = 300
    return replace(data, table=SampledLog("table", 2000.0, data.table.time_s[:n],
                                          {k: v[:n] for k, v in data.table.channels.items()}))


@pytest.mark.parametrize("spoil", [None, _no_trigger, _half_latched, _short],
                         ids=["plain", "no-trigger", "unlatched", "short"])
@pytest.mark.parametrize(("latch", "drift_ppm", "seed"),
                         [(True, 40.0, 1), (True, -250.0, 2), (False, 12.0, 3)])
def test_clock_relation_equals_the_plain_one(  # type: ignore[no-untyped-def]
        spoil, latch: bool, drift_ppm: float, seed: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    data = make_step(sine_step("s", 8, 100.0), SynthRig(drift_ppm=drift_ppm, latch=latch),
                     seed=seed)
    if spoil is not None:
        data = spoil(data)
    try:
        fast = freeze_pulse.clock_relation(data)
    except AnalysisError as exc:
        fast_error = str(exc)
    else:
        fast_error = None
    monkeypatch.setattr(clock_fit, "pair_edges", _plain_pair_edges)
    try:
        plain = _reference_relation(data)
    except AnalysisError as exc:
        assert fast_error == str(exc)
        return
    assert fast_error is None
    assert repr(fast) == repr(plain)  # every field, NaN and all, to the last digit


def test_rising_edges_as_before() -> None:
    rng = np.random.default_rng(0)
    pulse = (rng.random(10_000) > 0.5).astype(float)
    pulse[::7] = 0.5  # on the threshold: low
    high = pulse > clock_fit.LOGIC_THRESHOLD
    expected = np.flatnonzero(~high[:-1] & high[1:]) + 1
    assert np.array_equal(clock_fit.rising_edges(pulse), expected)
    assert clock_fit.rising_edges(np.array([1.0])).size == 0
