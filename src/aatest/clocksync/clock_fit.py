"""Fitting the clock relation on the loggers' freeze-pulse edges (docs/method.md §2 (3)–(4)).

The edges of both logs are found (:func:`rising_edges`), paired and fitted: by least squares
through latch-corrected edge times (:func:`fit_clock_relation`, refined by the trigger in
:func:`refine_offset`), or, without latch times, through every edge's one-sample interval
(:func:`fit_unlatched_relation`, :mod:`aatest.clocksync.edges`). :func:`edge_relation` chooses
between the two; both the eager (:mod:`aatest.clocksync.freeze_pulse`) and the streamed
(:mod:`aatest.clocksync.streamed`) synchronisation call it.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from aatest.clocksync.edges import (
    LAG_SAMPLES,
    MIN_EDGES,
    check_counts,
    check_paired,
    correct_slips,
    interval_fit,
    line_fit,
    pair_edges,
)
from aatest.clocksync.relation import ClockRelation
from aatest.engine.errors import AnalysisError
from aatest.engine.logs import SampledLog
from aatest.recording.dataset import StepData

#: a paired edge further than this fraction of the pulse period from the fit is inconsistent
_PAIR_TOLERANCE_PERIODS = 0.25


#: a 0/1 logic level is high above half its swing
LOGIC_THRESHOLD = 0.5


def rising_edges(pulse: np.ndarray) -> np.ndarray:
    """Indices of the samples where a 0/1 pulse goes from low to high."""
    high = np.asarray(pulse) > LOGIC_THRESHOLD
    # high after low is True > False: one comparison, no inverted copy of the whole log
    return np.flatnonzero(high[1:] > high[:-1]) + 1


#: time stamps a straight line needs
_MIN_FIT_SAMPLES = 2


def regular_fit(time_s: np.ndarray) -> tuple[float, float]:
    """(intercept s, slope s/sample) of the time stamps' straight line against the index."""
    if time_s.size < _MIN_FIT_SAMPLES or not np.all(np.isfinite(time_s)):
        raise AnalysisError(f"a log of {time_s.size} sample(s) or with non-finite time stamps "
                            "has no time base to fit")
    # the least-squares line in closed form about the index's centre: the line np.polyfit
    # finds (to rounding), without its SVD of an (n, 2) matrix, which cost ≈10 ms per 2^17
    # stamps, ≈3 s of CPU in a stepped-sine run (twice per step: recorded, then analysed).
    # NumPy's pairwise sums, not BLAS: the same bits whatever BLAS threads are allowed.
    n = time_s.size
    centre = 0.5 * (n - 1)
    index = np.arange(n, dtype=np.float64)
    index -= centre
    rel = time_s - time_s[0]
    mean = float(np.mean(rel))
    rel -= mean
    rel *= index
    slope = float(np.sum(rel)) / (n * (n * n - 1.0) / 12.0)  # Σ (i − centre)² in closed form
    return mean - slope * centre, slope


def regular_time(time_s: np.ndarray, fit: tuple[float, float] | None = None) -> np.ndarray:
    """Replace jittered time stamps by their straight-line fit against the sample index.

    A crystal-clocked logger samples uniformly; its time-stamp jitter (≈6 µs on the DAQ) is
    noise of the stamps, not of the sampling, so the fit is the better time base. ``fit``: the
    line already fitted to these stamps (:func:`regular_fit`), else fitted here.
    """
    return regular_time_at(time_s, fit if fit is not None else regular_fit(time_s),
                           np.arange(time_s.size, dtype=np.float64))


def regular_time_at(time_s: np.ndarray, fit: tuple[float, float],
                    index: np.ndarray | int) -> np.ndarray:
    """:func:`regular_time`'s values at the sample ``index`` (non-negative) only: the same
    IEEE operations element by element, without the array of every sample.

    Why: the run-time check reads the DAQ's regular time base at its pulse edges, the trigger
    and the two ends only; building all 2^17 of it was ≈ 5 % of the check.
    """
    intercept, slope = fit
    return time_s[0] + intercept + slope * np.asarray(index, dtype=np.float64)


def _table_edges(table: SampledLog) -> tuple[np.ndarray, np.ndarray]:
    """(registering rows' table times, latch times or NaN) of the freeze-pulse rising edges.

    A latch value that is NaN (or a table without ``fp_latch_s``) means "not latched": that
    edge is only known to lie in the sample before its registering row (docs/interfaces.md §4).
    """
    idx = rising_edges(table["sync_pulse"])
    registered = np.asarray(table.time_s, dtype=np.float64)[idx]
    if "fp_latch_s" not in table.channels:
        return registered, np.full(idx.size, np.nan)
    return registered, np.asarray(table["fp_latch_s"], dtype=np.float64)[idx]


def daq_edges(data: StepData, daq_time_s: np.ndarray) -> tuple[np.ndarray, float | None]:
    """DAQ-clock times of the DAQ's sync-pulse rising edges, and the coarse table−DAQ offset.

    The trigger marks the table's first sample on the DAQ clock, so it aligns the two records
    to about one sample — far better than the half pulse period pairing needs. Without a
    trigger the first edges are aligned instead (docs/method.md §2 (3)).
    """
    idx, first = daq_edge_samples(data)
    if first is None:
        return daq_time_s[idx], None
    return daq_time_s[idx], float(data.table.time_s[0]) - float(daq_time_s[first])


def daq_edge_samples(data: StepData) -> tuple[np.ndarray, int | None]:
    """(DAQ sample indices of the sync-pulse rising edges at or after the trigger, the
    trigger's first high sample or None without a trigger channel): :func:`daq_edges` before
    any time base is read."""
    daq = data.daq
    idx = rising_edges(daq["sync_pulse"])
    if "trigger" not in daq.channels:
        return idx, None
    trigger = np.asarray(daq["trigger"]) > LOGIC_THRESHOLD
    if not trigger.any():
        raise AnalysisError(f"step {data.step.id}: the DAQ trigger never goes high")
    first = int(np.argmax(trigger))
    return idx[idx >= first], first


def fit_clock_relation(step_id: str, t_table: np.ndarray, t_daq: np.ndarray,
                       offset0: float | None = None, table_dt_s: float = 0.0) -> ClockRelation:
    """Fit ``t_table = offset + t_daq·(1 + drift)`` over all paired edges (docs/method.md §2 (4)).

    ``t_table`` are true (latch-corrected) edge times. Edges are paired in windows that double
    from the first second (:func:`aatest.clocksync.edges.pair_edges`), so drifts of hundreds of ppm
    still pair correctly; the relation is the least-squares line through the pairs.

    Raises
    ------
    AnalysisError
        When edges are missing, cannot be paired, or do not lie on one straight line.
    """
    period_s = check_counts(step_id, t_table, t_daq)
    tol_s = _PAIR_TOLERANCE_PERIODS * period_s
    pairs = pair_edges(step_id, t_table, t_daq, period_s, offset0, table_dt_s or 1e-6)
    tt, td = pairs.t_table, pairs.t_daq
    coef, residual = pairs.fit if pairs.fit is not None else line_fit(tt, td)
    coef = np.array([coef[0] - coef[1] * (td[0] - t_daq[0]), coef[1]])
    check_paired(step_id, tt.size, t_table, t_daq, coef, float(np.max(np.abs(residual))), tol_s)
    sigma = float(np.sqrt(residual @ residual / max(tt.size - 2, 1)))
    slope = float(coef[1])
    return ClockRelation(
        offset_s=float(coef[0] - slope * t_daq[0]),
        drift_ppm=(slope - 1.0) * 1e6,
        residual_rms_us=float(np.sqrt(np.mean(residual**2))) * 1e6,
        edges_used=int(tt.size),
        drift_u_ppm=sigma / float(np.sqrt(np.sum((td - td.mean()) ** 2))) * 1e6,
        fit_span_daq_s=(float(td[0]), float(td[-1])),
    )


def fit_unlatched_relation(step_id: str, registered_s: np.ndarray, t_daq: np.ndarray,
                           table_dt_s: float, daq_dt_s: float,
                           trigger: tuple[float, float] | None = None,
                           slope_range: tuple[float, float] | None = None) -> ClockRelation:
    """The clock relation from edges known only to their registering table sample.

    Pairs the edges (their centre estimates), undoes one-sample slips and takes the centre of
    the set of lines through every edge's interval (:mod:`aatest.clocksync.edges`). A DAQ edge is
    logged on its first high sample, so the fitted line is that of the DAQ's edge samples; the
    trigger (``(table time of the first row, DAQ time of the trigger)``), generated on one of
    the DAQ's samples, sets the offset (:func:`refine_offset` does the same with latch
    times); a trigger the edges contradict (wired differently) is not used, and the DAQ
    sample's ambiguity stays in the offset. The trigger never bounds the rate: loggers mark
    the table's first row on the DAQ sample before it (aatest's trigger starts the log), on
    the one after it (docs/interfaces.md §3) or on the nearest, and an interval that assumed
    one of them tilted the lines of the others until it excluded their true rate (−40 ppm
    fitted as −2.9). ``drift_u_ppm`` and ``offset_u_s`` are uniform over the set;
    ``offset_u_s`` is the alignment's at the record's centre (where an analysis of the whole
    record feels it), not at DAQ time zero: with the trigger, the slope range times the
    distance from it and the trigger's own ±1 DAQ sample (the conventions above).
    """
    period_s = check_counts(step_id, registered_s, t_daq)
    lag_s = 0.5 * sum(LAG_SAMPLES) * table_dt_s
    offset0 = None if trigger is None else trigger[0] - trigger[1]
    pairs = pair_edges(step_id, registered_s - lag_s, t_daq, period_s, offset0, table_dt_s)
    corrected, slips = correct_slips(pairs.t_table + lag_s, pairs.t_daq, table_dt_s)
    fit = interval_fit(step_id, corrected, pairs.t_daq, table_dt_s, slope_range)
    pin = None if trigger is None else (trigger[1], trigger[0] - daq_dt_s, trigger[0] + daq_dt_s)
    if pin is not None:
        try:  # the trigger sets the offset only where the edges allow it; never the rate
            interval_fit(step_id, corrected, pairs.t_daq, table_dt_s, fit.slope_range, pin)
        except AnalysisError:
            pin = None  # the trigger disagrees with the edges: not where the contract puts it
    coef = np.array([fit.intercept_s - fit.slope * (fit.x0_s - t_daq[0]), fit.slope])
    check_paired(step_id, pairs.t_daq.size, registered_s - lag_s, t_daq, coef, 0.0, 1.0)
    slope, b_lo, b_hi = fit.slope, *fit.slope_range
    mid_daq_s = fit.x0_s + fit.x_mid_s
    if pin is not None and trigger is not None:  # the line passes the trigger: only b is open
        offset = trigger[0] - slope * trigger[1]
        offset_u = float(np.hypot((b_hi - b_lo) * abs(mid_daq_s - trigger[1]),
                                  2.0 * daq_dt_s) / np.sqrt(12.0))
    else:  # the true edges lie up to one DAQ sample before the logged ones
        offset = fit.intercept_s - slope * fit.x0_s + 0.5 * slope * daq_dt_s
        offset_u = float(np.sqrt((fit.mid_range_s[1] - fit.mid_range_s[0]) ** 2
                                 + (slope * daq_dt_s) ** 2) / np.sqrt(12.0))
    return ClockRelation(
        offset_s=float(offset),
        drift_ppm=(slope - 1.0) * 1e6,
        residual_rms_us=fit.residual_rms_s * 1e6,
        edges_used=int(pairs.t_daq.size),
        drift_u_ppm=(b_hi - b_lo) / float(np.sqrt(12.0)) * 1e6,
        offset_u_s=float(offset_u),
        latched=False,
        slips_corrected=slips,
        slope_range=(b_lo, b_hi),
        record_mid_daq_s=mid_daq_s,
        fit_span_daq_s=(float(pairs.t_daq[0]), float(pairs.t_daq[-1])),
    )


def refine_offset(relation: ClockRelation, table_t0_s: float, trigger_daq_s: float | None,
                  daq_dt_s: float) -> ClockRelation:
    """Pin the offset with the trigger when the DAQ's pulse edges fall between its samples.

    A DAQ edge is logged on its first high sample, so the true edge may lie up to one DAQ
    sample earlier: the edge-based offset is the lower end of an interval one sample wide.
    The trigger is generated by the DAQ on one of its samples and starts the table log, so
    the table's first sample *is* that DAQ instant. When the trigger-based offset lies inside
    the edge interval (the two agree) it is taken; otherwise (a trigger wired differently)
    the edge-based offset stands, with the edge interval's rectangular standard uncertainty
    (one DAQ sample/√12) as ``offset_u_s``. A pinned offset's ``offset_u_s`` is the fitted
    rate's uncertainty carried to the trigger instant combined with the edges' scatter about
    the line (σ/√n): on the twin it matches the offset's error over seeds, where one sample
    (144 µs at 2 kHz) overstated it a thousandfold.
    """
    if trigger_daq_s is None:
        return relation
    k = 1.0 + relation.drift_ppm * 1e-6
    width = daq_dt_s * k
    from_trigger = table_t0_s - trigger_daq_s * k
    if relation.offset_s - 1e-3 * width <= from_trigger < relation.offset_s + width:
        # pinned: the rate's uncertainty carried to the trigger instant, and the edges'
        # scatter about the line at the mean (the trigger was accepted against it)
        u_rate = abs(trigger_daq_s) * relation.drift_u_ppm * 1e-6
        u_line = relation.residual_rms_us * 1e-6 / np.sqrt(max(relation.edges_used, 1))
        return replace(relation, offset_s=float(from_trigger),
                       offset_u_s=float(np.hypot(u_rate, u_line)))
    return replace(relation, offset_u_s=float(width / np.sqrt(12.0)))


#: latch-corrected edges are used alone when at least this share of the edges has a latch time
_MIN_LATCHED_FRACTION = 0.5


def edge_relation(step_id: str, table: SampledLog, daq_rate_hz: float, t_daq: np.ndarray,
                  offset0: float | None, slope_range: tuple[float, float] | None = None
                  ) -> ClockRelation:
    """The relation of a table log and the DAQ's edge times ``t_daq`` (s, DAQ clock), fitted
    on the paired edges (latched, else their registering samples); ``offset0`` the coarse
    offset from the trigger."""
    registered, latch = _table_edges(table)
    table_t0 = float(table.time_s[0])
    trigger_daq_s = None if offset0 is None else table_t0 - offset0
    daq_dt = 1.0 / daq_rate_hz
    latched = np.isfinite(latch)
    if latched.sum() >= max(MIN_EDGES, _MIN_LATCHED_FRACTION * latch.size):
        relation = fit_clock_relation(step_id, (registered - latch)[latched], t_daq,
                                      offset0, 1.0 / float(table.sample_rate_hz))
        return refine_offset(relation, table_t0, trigger_daq_s, daq_dt)
    trigger = None if trigger_daq_s is None else (table_t0, trigger_daq_s)
    return fit_unlatched_relation(step_id, registered, t_daq,
                                  1.0 / float(table.sample_rate_hz), daq_dt, trigger,
                                  slope_range)
