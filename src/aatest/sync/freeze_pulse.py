"""Freeze-pulse synchronisation of the table log and the sensor (DAQ) log (docs/method.md §2).

The DAQ generates a 100 Hz sync pulse that the table registers as its freeze pulse one
controller cycle late, logging the latch time ``fp_latch_s``. The true edge time on the table
clock is ``time_s − fp_latch_s`` on the 0→1 row; on the DAQ clock it is the sample where the
DAQ's own pulse goes 0→1. All paired edges give the linear clock relation (docs/interfaces.md §4)

    t_table = offset_s + t_daq · (1 + drift_ppm · 1e-6),

and the DAQ channels are resampled onto the table's uniform time vector, so every analysis
reads both loggers on one time base. Without ``fp_latch_s`` (or where it is NaN, "not
latched") an edge is only known to lie in the sample before its registering row; the relation
is then the centre of the lines through every edge's interval (:mod:`aatest.sync.edges`).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
from scipy.interpolate import CubicSpline

from aatest.engine.dataset import Dataset, StepData
from aatest.engine.errors import AnalysisError
from aatest.engine.logs import SampledLog
from aatest.engine.steps import PlannedStep
from aatest.sync.edges import (
    LAG_SAMPLES,
    MIN_EDGES,
    check_counts,
    check_paired,
    correct_slips,
    interval_fit,
    line_fit,
    pair_edges,
)

if TYPE_CHECKING:  # the streamed record builds on this module; only its type is needed here
    from aatest.sync.streamed import StreamedRecord

#: a paired edge further than this fraction of the pulse period from the fit is inconsistent
_PAIR_TOLERANCE_PERIODS = 0.25
_DIGITAL = ("sync_pulse", "trigger")


@dataclass(frozen=True)
class ClockRelation:
    """``t_table = offset_s + t_daq·(1 + drift_ppm·1e-6)`` and how well the edges agree."""

    offset_s: float
    drift_ppm: float
    residual_rms_us: float
    edges_used: int
    drift_u_ppm: float = 0.0
    offset_u_s: float = 0.0
    #: (intercept s, slope s/sample) of the DAQ's time stamps against their index, when known:
    #: re-synchronising the step then rebuilds its regular DAQ time base without refitting
    daq_time_fit: tuple[float, float] | None = None
    #: whether the edge times came from latch times (else: from their registering samples)
    latched: bool = True
    #: registrations one sample off the pattern, undone before the fit (no latch times)
    slips_corrected: int = 0
    #: slopes (1 + drift) every line through the edge intervals has (no latch times): what a
    #: fit of several records of one crystal intersects
    slope_range: tuple[float, float] | None = None
    #: DAQ time of the record's centre, where ``offset_u_s`` holds without latch times
    record_mid_daq_s: float | None = None
    #: DAQ-clock span (s) of the paired edges the relation is fitted on, and of the DAQ record:
    #: a table log covering part of the record (a finite controller buffer) fits the clocks on
    #: the edges both loggers hold and carries the fitted drift over the rest
    fit_span_daq_s: tuple[float, float] | None = None
    record_span_daq_s: tuple[float, float] | None = None

    @property
    def fit_coverage(self) -> float:
        """Share of the DAQ record's span that the fitted edges span (1.0 when unknown)."""
        if self.fit_span_daq_s is None or self.record_span_daq_s is None:
            return 1.0
        record = self.record_span_daq_s[1] - self.record_span_daq_s[0]
        fitted = self.fit_span_daq_s[1] - self.fit_span_daq_s[0]
        return float(min(1.0, fitted / record)) if record > 0 else 1.0

    @property
    def extrapolation_u_s(self) -> float:
        """Standard uncertainty (s) the carried drift adds to the time alignment at the record
        point farthest outside the fitted edges: ``u(drift)·distance`` (0 when they span it)."""
        if self.fit_span_daq_s is None or self.record_span_daq_s is None:
            return 0.0
        beyond = max(self.fit_span_daq_s[0] - self.record_span_daq_s[0],
                     self.record_span_daq_s[1] - self.fit_span_daq_s[1], 0.0)
        return float(self.drift_u_ppm * 1e-6 * beyond)

    def to_table_s(self, t_daq_s: np.ndarray) -> np.ndarray:
        """Map DAQ-clock times (s) to table-clock times (s)."""
        return self.offset_s + np.asarray(t_daq_s) * (1.0 + self.drift_ppm * 1e-6)

    def to_daq_s(self, t_table_s: np.ndarray) -> np.ndarray:
        """Map table-clock times (s) to DAQ-clock times (s)."""
        return (np.asarray(t_table_s) - self.offset_s) / (1.0 + self.drift_ppm * 1e-6)

    def as_dict(self) -> dict[str, float | int | bool]:
        """The contract ``sync`` keys plus the drift's standard uncertainty."""
        return {
            "drift_ppm": self.drift_ppm,
            "offset_s": self.offset_s,
            "residual_rms_us": self.residual_rms_us,
            "edges_used": self.edges_used,
            "drift_u_ppm": self.drift_u_ppm,
            "offset_u_s": self.offset_u_s,
            "latched": self.latched,
            "slips_corrected": self.slips_corrected,
            "fit_coverage": self.fit_coverage,
            "extrapolation_u_s": self.extrapolation_u_s,
        }


@dataclass(frozen=True)
class SyncedStep:
    """One step with both loggers on the table's time vector.

    ``table`` holds the table channels (trimmed to the DAQ coverage), ``daq`` the DAQ channels
    resampled onto ``time_s`` (analog channels by cubic spline, digital ones by nearest sample;
    after :func:`synchronise`, each when first read).
    """

    step: PlannedStep
    time_s: np.ndarray
    sample_rate_hz: float
    table: Mapping[str, np.ndarray]
    daq: Mapping[str, np.ndarray]
    relation: ClockRelation
    #: a long record whose table log covers its head only (:mod:`aatest.sync.streamed`):
    #: the whole DAQ record, read block by block; ``time_s``/``table``/``daq`` are the head
    record: StreamedRecord | None = None

    def __len__(self) -> int:
        """Samples of the record (the whole DAQ record of a streamed one)."""
        return self.record.samples if self.record is not None else int(self.time_s.shape[0])

    def daq_blocks(self, channels: Sequence[str]) -> Iterator[dict[str, np.ndarray]]:
        """The record's DAQ ``channels`` (those it has) in consecutive blocks: one block of
        the arrays above, or a streamed record piece by piece (nothing held whole)."""
        if self.record is not None:
            yield from self.record.blocks(channels)
            return
        yield {ch: np.asarray(self.daq[ch]) for ch in channels if ch in self.daq}


#: a 0/1 logic level is high above half its swing
LOGIC_THRESHOLD = 0.5


def rising_edges(pulse: np.ndarray) -> np.ndarray:
    """Indices of the samples where a 0/1 pulse goes from low to high."""
    high = np.asarray(pulse) > LOGIC_THRESHOLD
    return np.flatnonzero(~high[:-1] & high[1:]) + 1


#: time stamps a straight line needs
_MIN_FIT_SAMPLES = 2


def _regular_fit(time_s: np.ndarray) -> tuple[float, float]:
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


def _regular_time(time_s: np.ndarray, fit: tuple[float, float] | None = None) -> np.ndarray:
    """Replace jittered time stamps by their straight-line fit against the sample index.

    A crystal-clocked logger samples uniformly; its time-stamp jitter (≈6 µs on the DAQ) is
    noise of the stamps, not of the sampling, so the fit is the better time base. ``fit``: the
    line already fitted to these stamps (:func:`_regular_fit`), else fitted here.
    """
    intercept, slope = fit if fit is not None else _regular_fit(time_s)
    return time_s[0] + intercept + slope * np.arange(time_s.size, dtype=np.float64)


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


def _daq_edges(data: StepData, daq_time_s: np.ndarray) -> tuple[np.ndarray, float | None]:
    """DAQ-clock times of the DAQ's sync-pulse rising edges, and the coarse table−DAQ offset.

    The trigger marks the table's first sample on the DAQ clock, so it aligns the two records
    to about one sample — far better than the half pulse period pairing needs. Without a
    trigger the first edges are aligned instead (docs/method.md §2 (3)).
    """
    daq = data.daq
    idx = rising_edges(daq["sync_pulse"])
    if "trigger" not in daq.channels:
        return daq_time_s[idx], None
    trigger = np.asarray(daq["trigger"]) > LOGIC_THRESHOLD
    if not trigger.any():
        raise AnalysisError(f"step {data.step.id}: the DAQ trigger never goes high")
    first = int(np.argmax(trigger))
    offset0 = float(data.table.time_s[0]) - float(daq_time_s[first])
    return daq_time_s[idx[idx >= first]], offset0


def fit_clock_relation(step_id: str, t_table: np.ndarray, t_daq: np.ndarray,
                       offset0: float | None = None, table_dt_s: float = 0.0) -> ClockRelation:
    """Fit ``t_table = offset + t_daq·(1 + drift)`` over all paired edges (docs/method.md §2 (4)).

    ``t_table`` are true (latch-corrected) edge times. Edges are paired in windows that double
    from the first second (:func:`aatest.sync.edges.pair_edges`), so drifts of hundreds of ppm
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
    coef, residual = line_fit(tt, td)
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
    the set of lines through every edge's interval (:mod:`aatest.sync.edges`). A DAQ edge is
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


class _Resampled(Mapping[str, np.ndarray]):
    """DAQ channels at the DAQ-clock instants ``at_daq_s``, each resampled when first read.

    Why lazily: an analysis reads one or two of a step's DAQ channels (a sensor's volts), and
    a cubic spline through a 2^17-sample record is the costliest part of synchronising it.
    """

    def __init__(self, daq_time_s: np.ndarray, channels: Mapping[str, np.ndarray],
                 at_daq_s: np.ndarray) -> None:
        self._time_s, self._channels, self._at_s = daq_time_s, channels, at_daq_s
        self._done: dict[str, np.ndarray] = {}

    def __getitem__(self, name: str) -> np.ndarray:
        if name not in self._done:
            self._done[name] = _resample(self._time_s, name, self._channels[name], self._at_s)
        return self._done[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._channels)

    def __len__(self) -> int:
        return len(self._channels)


def _resample(daq_time_s: np.ndarray, name: str, values: np.ndarray,
              at_daq_s: np.ndarray) -> np.ndarray:
    """One DAQ channel at the DAQ-clock instants ``at_daq_s`` (digital: nearest sample)."""
    if name in _DIGITAL:
        idx = np.clip(np.searchsorted(daq_time_s, at_daq_s), 0, daq_time_s.size - 1)
        picked: np.ndarray = np.asarray(values)[idx]
        return picked
    spline: np.ndarray = CubicSpline(daq_time_s, np.asarray(values, dtype=np.float64))(at_daq_s)
    return spline


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


def clock_relation(data: StepData,
                   slope_range: tuple[float, float] | None = None) -> ClockRelation:
    """The DAQ-to-table clock relation of one step, checked like :func:`synchronise` checks it,
    without resampling anything (for summaries that need no samples).

    ``slope_range``: the slopes (1 + drift) other records of the same DAQ crystal allow
    (:func:`~aatest.sync.edges.joint_slope_range`); without latch times the step's own range
    is intersected with it, so a short record takes the rate its neighbours pin down.
    """
    if _partial(data):  # a long record the table logged the head of
        from aatest.sync.streamed import log_pieces, streamed_relation

        return streamed_relation(data.step, data.table, log_pieces(data.daq))
    time_s = np.asarray(data.daq.time_s, dtype=np.float64)
    fit = _regular_fit(time_s)
    daq_time_s = _regular_time(time_s, fit)
    known = None if slope_range is None else _fitted_relation(data, daq_time_s, slope_range)
    return replace(_relation(data, daq_time_s, known)[0], daq_time_fit=fit)


def _partial(data: StepData) -> bool:
    """Whether the step's table log covers only the head of its record (a finite buffer)."""
    from aatest.sync.streamed import is_partial

    return is_partial(data.step, data.samples("table"), data.samples("daq"))


def _relation(data: StepData, daq_time_s: np.ndarray, known: ClockRelation | None = None
              ) -> tuple[ClockRelation, np.ndarray, slice]:
    """The step's clock relation (``known``: already fitted), the table instants on the DAQ
    clock (s) and the covered part."""
    relation = known if known is not None else _fitted_relation(data, daq_time_s)
    at_daq_s = relation.to_daq_s(np.asarray(data.table.time_s, dtype=np.float64))
    inside = np.flatnonzero((at_daq_s >= daq_time_s[0]) & (at_daq_s <= daq_time_s[-1]))
    if inside.size < 0.5 * at_daq_s.size:
        raise AnalysisError(f"step {data.step.id}: the DAQ record covers < 50 % of the table log")
    return relation, at_daq_s, slice(int(inside[0]), int(inside[-1]) + 1)


#: latch-corrected edges are used alone when at least this share of the edges has a latch time
_MIN_LATCHED_FRACTION = 0.5


def _fitted_relation(data: StepData, daq_time_s: np.ndarray,
                     slope_range: tuple[float, float] | None = None) -> ClockRelation:
    """The step's relation from its latched edges (NaN latch values left out) when most edges
    have one, else from the registering samples of all (:func:`fit_unlatched_relation`)."""
    t_daq, offset0 = _daq_edges(data, daq_time_s)
    span = (float(daq_time_s[0]), float(daq_time_s[-1]))
    return replace(_edge_relation(data, t_daq, offset0, slope_range), record_span_daq_s=span)


def _edge_relation(data: StepData, t_daq: np.ndarray, offset0: float | None,
                   slope_range: tuple[float, float] | None) -> ClockRelation:
    """The relation fitted on the paired edges (latched or registering samples)."""
    return edge_relation(data.step.id, data.table, float(data.daq.sample_rate_hz), t_daq,
                         offset0, slope_range)


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


def synchronise(data: StepData, relation: ClockRelation | None = None) -> SyncedStep:
    """Synchronise one step: clock relation from all edges, trim, resample onto the table grid.

    Parameters
    ----------
    data
        A recorded step with a table log (``sync_pulse``, optionally ``fp_latch_s``) and a DAQ
        log (``sync_pulse``, ``trigger``, sensor volts) on their own clocks.
    relation
        Its clock relation when already fitted (:func:`clock_relation`), else fitted here.

    Returns
    -------
    SyncedStep
        Table samples covered by the DAQ record, with the DAQ channels on the same instants.
    """
    if _partial(data):  # a long record the table logged the head of: read piece by piece
        from aatest.sync.streamed import log_pieces, synchronise_streamed

        return synchronise_streamed(data.step, data.table, log_pieces(data.daq), relation)
    daq_time_s = _regular_time(np.asarray(data.daq.time_s, dtype=np.float64),
                               relation.daq_time_fit if relation is not None else None)
    relation, at_daq_s, keep = _relation(data, daq_time_s, relation)  # keep: contiguous
    table_time_s = np.asarray(data.table.time_s, dtype=np.float64)
    table = {name: np.asarray(v)[keep] for name, v in data.table.channels.items()}
    daq = _Resampled(daq_time_s, data.daq.channels, at_daq_s[keep])
    return SyncedStep(
        step=data.step,
        time_s=table_time_s[keep],
        sample_rate_hz=float(data.table.sample_rate_hz),
        table=table,
        daq=daq,
        relation=relation,
    )


def synchronise_all(data: Dataset) -> list[SyncedStep]:
    """Every recorded step of a dataset synchronised (steps not recorded are left out).

    Raises
    ------
    AnalysisError
        Naming the first step whose sync edges are missing or inconsistent.
    """
    return [synchronise(s) for s in data.steps if s.step.recorded]
