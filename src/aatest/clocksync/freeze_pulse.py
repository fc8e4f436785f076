"""Freeze-pulse synchronisation of the table log and the sensor (DAQ) log (docs/method.md §2).

The DAQ generates a 100 Hz sync pulse that the table registers as its freeze pulse one
controller cycle late, logging the latch time ``fp_latch_s``. The true edge time on the table
clock is ``time_s − fp_latch_s`` on the 0→1 row; on the DAQ clock it is the sample where the
DAQ's own pulse goes 0→1. All paired edges give the linear clock relation (docs/interfaces.md §4)

    t_table = offset_s + t_daq · (1 + drift_ppm · 1e-6),

and the DAQ channels are resampled onto the table's uniform time vector, so every analysis
reads both loggers on one time base. Without ``fp_latch_s`` (or where it is NaN, "not
latched") an edge is only known to lie in the sample before its registering row; the relation
is then the centre of the lines through every edge's interval (:mod:`aatest.clocksync.edges`).
"""

from __future__ import annotations

from bisect import bisect_left
from collections.abc import Iterator, Mapping
from dataclasses import replace

import numpy as np

from aatest.clocksync.clock_fit import (
    LOGIC_THRESHOLD,
    daq_edge_samples,
    daq_edges,
    edge_relation,
    fit_clock_relation,
    fit_unlatched_relation,
    refine_offset,
    regular_fit,
    regular_time,
    regular_time_at,
    rising_edges,
)
from aatest.clocksync.relation import ClockRelation, SyncedStep
from aatest.clocksync.spline import uniform_cubic_spline, uniform_index
from aatest.clocksync.streamed import (
    is_partial,
    log_pieces,
    streamed_relation,
    synchronise_streamed,
)
from aatest.engine.errors import AnalysisError
from aatest.recording.dataset import Dataset, StepData

# the fitting (aatest.clocksync.clock_fit) and the records (aatest.clocksync.relation) live in
# modules of their own, which the streamed path shares; their names stay importable from here
__all__ = ["LOGIC_THRESHOLD", "ClockRelation", "SyncedStep", "clock_relation", "edge_relation",
           "fit_and_synchronise", "fit_clock_relation", "fit_unlatched_relation", "refine_offset",
           "rising_edges", "synchronise", "synchronise_all"]

_DIGITAL = ("sync_pulse", "trigger")


class _Resampled(Mapping[str, np.ndarray]):
    """DAQ channels at the DAQ-clock instants ``at_daq_s``, each resampled when first read.

    Why lazily: an analysis reads one or two of a step's DAQ channels (a sensor's volts), and
    a cubic spline through a 2^17-sample record is the costliest part of synchronising it
    (≈ 5 ms on uniform knots, :mod:`aatest.clocksync.spline`).
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
    """One DAQ channel at the DAQ-clock instants ``at_daq_s`` (digital: nearest sample; analog:
    the not-a-knot cubic spline, on the uniform time base of :func:`regular_time`)."""
    if name in _DIGITAL:
        idx = np.clip(np.searchsorted(daq_time_s, at_daq_s), 0, daq_time_s.size - 1)
        picked: np.ndarray = np.asarray(values)[idx]
        return picked
    return uniform_cubic_spline(values, uniform_index(daq_time_s, at_daq_s))


def clock_relation(data: StepData,
                   slope_range: tuple[float, float] | None = None) -> ClockRelation:
    """The DAQ-to-table clock relation of one step, checked like :func:`synchronise` checks it,
    without resampling anything (for summaries that need no samples).

    ``slope_range``: the slopes (1 + drift) other records of the same DAQ crystal allow
    (:func:`~aatest.clocksync.edges.joint_slope_range`); without latch times the step's own range
    is intersected with it, so a short record takes the rate its neighbours pin down.
    """
    if _partial(data):  # a long record the table logged the head of
        return streamed_relation(data.step, data.table, log_pieces(data.daq))
    time_s = np.asarray(data.daq.time_s, dtype=np.float64)
    fit = regular_fit(time_s)
    # the regular DAQ time base at the edges, the trigger and the ends only (the values
    # regular_time gives there): _fitted_relation's work without the array of every sample
    idx, first = daq_edge_samples(data)
    t_daq = regular_time_at(time_s, fit, idx)
    offset0 = (None if first is None else
               float(data.table.time_s[0]) - float(regular_time_at(time_s, fit, first)))
    span = (float(regular_time_at(time_s, fit, 0)),
            float(regular_time_at(time_s, fit, time_s.size - 1)))
    relation = replace(_edge_relation(data, t_daq, offset0, slope_range),
                       record_span_daq_s=span)
    table_time_s = np.asarray(data.table.time_s, dtype=np.float64)
    if not _covers_ordered(table_time_s, span, relation):
        # the general check (raises when not covered)
        _relation(data, regular_time(time_s, fit), relation)
    return replace(relation, daq_time_fit=fit)


def _covers_ordered(table_time_s: np.ndarray, daq_span_s: tuple[float, float],
                    relation: ClockRelation) -> bool:
    """Whether the DAQ record covers ≥ 50 % of the table log, decided as :func:`_relation`
    decides it but without mapping every table sample (False: not decidable so, or not covered).

    Table times in order and a rising relation map monotonically, sample by sample the same
    IEEE operations, so the samples inside the DAQ record are one run of indices whose ends
    two bisections find, each mapping a single sample: the check of every recorded step
    (run-time and analysis) no longer maps 2^17 samples it then throws away.
    """
    n = table_time_s.size
    rate = 1.0 + relation.drift_ppm * 1e-6
    if n == 0 or not rate > 0.0 or not bool(np.all(table_time_s[1:] >= table_time_s[:-1])):
        return False

    def at_daq_s(i: int) -> float:
        return float(relation.to_daq_s(table_time_s[i: i + 1])[0])

    first_in = bisect_left(range(n), True, key=lambda i: at_daq_s(i) >= daq_span_s[0])
    first_after = bisect_left(range(n), True, key=lambda i: at_daq_s(i) > daq_span_s[1])
    return first_after - first_in >= 0.5 * n


def _partial(data: StepData) -> bool:
    """Whether the step's table log covers only the head of its record (a finite buffer)."""
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


def _fitted_relation(data: StepData, daq_time_s: np.ndarray,
                     slope_range: tuple[float, float] | None = None) -> ClockRelation:
    """The step's relation from its latched edges (NaN latch values left out) when most edges
    have one, else from the registering samples of all (:func:`fit_unlatched_relation`)."""
    t_daq, offset0 = daq_edges(data, daq_time_s)
    span = (float(daq_time_s[0]), float(daq_time_s[-1]))
    return replace(_edge_relation(data, t_daq, offset0, slope_range), record_span_daq_s=span)


def _edge_relation(data: StepData, t_daq: np.ndarray, offset0: float | None,
                   slope_range: tuple[float, float] | None) -> ClockRelation:
    """The relation fitted on the paired edges (latched or registering samples)."""
    return edge_relation(data.step.id, data.table, float(data.daq.sample_rate_hz), t_daq,
                         offset0, slope_range)


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
        return synchronise_streamed(data.step, data.table, log_pieces(data.daq), relation)
    daq_time_s = regular_time(np.asarray(data.daq.time_s, dtype=np.float64),
                               relation.daq_time_fit if relation is not None else None)
    return _synchronised(data, daq_time_s, relation)


def fit_and_synchronise(data: StepData) -> SyncedStep:
    """:func:`synchronise` of a step with its :func:`clock_relation` (the synchronised step's
    ``relation``, its DAQ time fit included): the same values, the DAQ's regular time base
    made once, not once for the fit and again for the resampling (the sync pass's watches)."""
    if _partial(data):
        return synchronise(data, clock_relation(data))
    time_s = np.asarray(data.daq.time_s, dtype=np.float64)
    fit = regular_fit(time_s)
    daq_time_s = regular_time(time_s, fit)
    relation = replace(_fitted_relation(data, daq_time_s), daq_time_fit=fit)
    return _synchronised(data, daq_time_s, relation)


def _synchronised(data: StepData, daq_time_s: np.ndarray,
                  relation: ClockRelation | None) -> SyncedStep:
    """A whole record synchronised on its regular DAQ time base ``daq_time_s`` (the relation
    fitted here when None; refused when the DAQ record covers < 50 % of the table log)."""
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
