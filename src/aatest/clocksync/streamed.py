"""Synchronisation of a long record whose table log covers only part of it (docs/method.md §2).

A controller's log buffer is finite: during an hours-long static record streamed by the DAQ,
the table logs at full rate only as long as its buffer holds (the head of the record). The
clocks are fitted on the freeze-pulse edges both loggers hold and the fitted drift is carried
over the rest of the record; :class:`~aatest.clocksync.relation.ClockRelation` states the share
of the record the fitted edges span (``fit_coverage``) and what carrying the drift adds to the
alignment at the far end (``extrapolation_u_s``).

Bounded memory: the DAQ record is read piece by piece (its recorded blocks) — its time stamps'
straight line, its pulse edges and its trigger are reduced on the way (:func:`scan_daq`) — and
the analyses read the synchronised record block by block (:class:`StreamedRecord`), so no
array of the whole record is ever built, whatever its length.
"""

from __future__ import annotations

from collections.abc import Callable, Container, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from aatest.clocksync.clock_fit import edge_relation
from aatest.clocksync.relation import ClockRelation, SyncedStep
from aatest.clocksync.spline import uniform_cubic_spline, uniform_index
from aatest.engine.errors import AnalysisError
from aatest.engine.logs import SampledLog
from aatest.engine.steps import PlannedStep

#: a 0/1 logic level is high above half its swing
_LOGIC_THRESHOLD = 0.5
#: DAQ edges beyond the table log's span are not kept: margin, s, and relative
_EDGE_MARGIN_S, _EDGE_MARGIN_REL = 1.0, 1e-3
#: samples a straight line needs
_MIN_LINE = 2

#: the DAQ log of one step as consecutive pieces with the time stamps and the named channels
Pieces = Callable[[Container[str] | None], Iterator[SampledLog]]


def is_partial(step: PlannedStep, table_samples: int, daq_samples: int) -> bool:
    """Whether a recorded step's table log covers only part of its record: a static record
    whose table logged fewer samples than planned while the DAQ logged the whole (a finite
    controller buffer during a streamed record). Decided from the sample counts alone."""
    return (step.kind == "static" and table_samples < step.samples
            and daq_samples > table_samples)


@dataclass
class _Line:
    """Least-squares line of time stamps against the sample index, merged piece by piece
    (Chan et al.'s pairwise update of means and co-moments: no cancellation over 10⁸ samples)."""

    n: int = 0
    mean_i: float = 0.0
    mean_t: float = 0.0
    s_ii: float = 0.0
    s_it: float = 0.0

    def add(self, first: int, t_s: np.ndarray) -> None:
        """Feed the stamps ``t_s`` (s, relative to the record's first) of samples ``first…``."""
        m = int(t_s.size)
        if m == 0:
            return
        index = np.arange(first, first + m, dtype=np.float64)
        mi, mt = float(index.mean()), float(t_s.mean())
        di, dt = index - mi, t_s - mt
        s_ii, s_it = float(di @ di), float(di @ dt)
        n = self.n + m
        d_i, d_t = mi - self.mean_i, mt - self.mean_t
        self.s_ii += s_ii + d_i * d_i * self.n * m / n
        self.s_it += s_it + d_i * d_t * self.n * m / n
        self.mean_i += d_i * m / n
        self.mean_t += d_t * m / n
        self.n = n

    def fit(self) -> tuple[float, float]:
        """(intercept s, slope s/sample), as :func:`~aatest.clocksync.clock_fit.regular_fit`."""
        if self.n < _MIN_LINE or self.s_ii <= 0.0:
            raise AnalysisError(f"a log of {self.n} sample(s) has no time base to fit")
        slope = self.s_it / self.s_ii
        return self.mean_t - slope * self.mean_i, slope


@dataclass(frozen=True)
class DaqScan:
    """What the DAQ record gives the clock fit: its length, the straight line of its time
    stamps, its trigger and its pulse edges (sample indices, up to ``edges_until``)."""

    samples: int
    first_time_s: float
    time_fit: tuple[float, float]
    rate_hz: float
    trigger: int | None = None
    edges: np.ndarray = field(default_factory=lambda: np.empty(0, np.int64))

    def time_s(self, index: np.ndarray | float) -> np.ndarray:
        """Regular DAQ-clock time (s) of sample ``index`` (the fitted line, not the jitter)."""
        intercept, slope = self.time_fit
        return np.asarray(self.first_time_s + intercept + slope * np.asarray(index, float))

    def index_of(self, t_daq_s: float) -> float:
        """Fractional sample index of DAQ-clock time ``t_daq_s``."""
        intercept, slope = self.time_fit
        return (t_daq_s - self.first_time_s - intercept) / slope


def _rising(high: np.ndarray, before: bool) -> np.ndarray:
    """Indices in ``high`` where the level goes low → high (``before``: the level before)."""
    prev = np.concatenate([[before], high[:-1]])
    return np.flatnonzero(~prev & high)


def scan_daq(pieces: Iterable[SampledLog], keep_edges_s: float) -> DaqScan:
    """Reduce the DAQ record, piece by piece, to :class:`DaqScan`.

    ``keep_edges_s``: DAQ edges are kept up to this long after the trigger (the table log's
    span and a margin); later ones have no table edge to pair with.
    """
    line, position = _Line(), 0
    first_s: float | None = None
    trigger: int | None = None
    high_before, has_trigger = False, True
    edges: list[np.ndarray] = []
    limit: int | None = None
    rate_hz = 0.0
    for piece in pieces:
        if first_s is None:
            first_s, rate_hz = float(piece.time_s[0]), float(piece.sample_rate_hz)
        line.add(position, np.asarray(piece.time_s, dtype=np.float64) - first_s)
        if trigger is None and has_trigger:
            has_trigger = "trigger" in piece.channels
            on = np.flatnonzero(np.asarray(piece["trigger"]) > _LOGIC_THRESHOLD) \
                if has_trigger else np.empty(0, int)
            trigger = position + int(on[0]) if on.size else None
        if trigger is not None and limit is None:
            limit = trigger + int(np.ceil(keep_edges_s * rate_hz))
        if limit is None or position < limit:
            high = np.asarray(piece["sync_pulse"]) > _LOGIC_THRESHOLD
            edges.append(position + _rising(high, high_before))
            high_before = bool(high[-1]) if high.size else high_before
        position += len(piece)
    if first_s is None:
        raise AnalysisError("the DAQ log holds no sample")
    found = np.concatenate(edges) if edges else np.empty(0, np.int64)
    if position:
        found = found[found > 0]  # the first sample has no level before it
    if limit is not None:
        found = found[found < limit]
    return DaqScan(position, first_s, line.fit(), rate_hz, trigger, found)


@dataclass(frozen=True)
class StreamedRecord:
    """The DAQ record of a long step between the table record's start and end (sample
    indices ``first``…``stop`` of the DAQ log, found through the clock relation), read block
    by block: what the static analyses reduce (mean, variance, spectrum, Allan deviation)."""

    pieces: Pieces
    first: int
    stop: int

    @property
    def samples(self) -> int:
        """DAQ samples in the record proper."""
        return self.stop - self.first

    def blocks(self, channels: Sequence[str]) -> Iterator[dict[str, np.ndarray]]:
        """The record's ``channels`` (those the log has) in consecutive blocks, in order."""
        position = 0
        for piece in self.pieces(list(channels)):
            lo, hi = max(self.first - position, 0), min(self.stop - position, len(piece))
            position += len(piece)
            if hi > lo:
                yield {ch: np.asarray(piece[ch])[lo:hi] for ch in channels
                       if ch in piece.channels}
            if position >= self.stop:
                return


def record_span(scan: DaqScan, table_t0_s: float, table_span_s: float,
                to_daq_s: Callable[[float], float]) -> tuple[int, int]:
    """DAQ sample indices ``(first, stop)`` of the table record ``[t0, t0 + span)`` (table
    clock), mapped through the clock relation ``to_daq_s``."""
    first = int(np.ceil(scan.index_of(to_daq_s(table_t0_s)) - 1e-6))
    stop = int(np.floor(scan.index_of(to_daq_s(table_t0_s + table_span_s)) + 1e-6))
    return max(first, 0), min(stop, scan.samples)


class HeadChannels(Mapping[str, np.ndarray]):
    """DAQ channels at the table log's instants (the head both loggers cover), each resampled
    when first read, from the DAQ pieces that span it (cubic spline; digital: nearest)."""

    def __init__(self, pieces: Pieces, scan: DaqScan, at_daq_s: np.ndarray,
                 names: Sequence[str], digital: Container[str]) -> None:
        self._pieces, self._scan, self._at_s = pieces, scan, at_daq_s
        self._names, self._digital = tuple(names), digital
        self._done: dict[str, np.ndarray] = {}

    def __getitem__(self, name: str) -> np.ndarray:
        if name not in self._names:
            raise KeyError(name)
        if name not in self._done:
            self._done[name] = self._resample(name)
        return self._done[name]

    def _resample(self, name: str) -> np.ndarray:
        stop = int(np.ceil(self._scan.index_of(float(self._at_s[-1])))) + 4
        parts, position = [], 0
        for piece in self._pieces([name]):
            parts.append(np.asarray(piece[name])[: max(stop - position, 0)])
            position += len(piece)
            if position >= stop:
                break
        values = np.concatenate(parts)
        time_s = self._scan.time_s(np.arange(values.size))
        if name in self._digital:
            idx = np.clip(np.searchsorted(time_s, self._at_s), 0, time_s.size - 1)
            picked: np.ndarray = values[idx]
            return picked
        return uniform_cubic_spline(values, uniform_index(time_s, self._at_s))

    def __iter__(self) -> Iterator[str]:
        return iter(self._names)

    def __len__(self) -> int:
        return len(self._names)




#: DAQ channels resampled by nearest sample (logic levels)
_DIGITAL = ("sync_pulse", "trigger")
#: the DAQ channels the clock fit reads
_SYNC_CHANNELS = ("sync_pulse", "trigger")
#: the table rate must exceed the pulse rate this many times for its edges to be resolved
MIN_RATE_OVER_PULSE = 2.0


def log_pieces(log: SampledLog, per: int = 2**17) -> Pieces:
    """A log held in memory as :data:`Pieces` of ``per`` samples (views, nothing copied)."""
    def pieces(channels: Container[str] | None) -> Iterator[SampledLog]:
        names = [n for n in log.channels if channels is None or n in channels]
        for lo in range(0, len(log), per):
            part = slice(lo, lo + per)
            yield SampledLog(log.source, log.sample_rate_hz, log.time_s[part],
                             {n: log.channels[n][part] for n in names}, dict(log.units))
    return pieces


def _edges_resolved(step: PlannedStep, table: SampledLog, pulse_hz: float) -> None:
    """Refuse a table log too slow to hold the freeze-pulse edges (1 Hz snapshots of a long
    record written by earlier versions) with a sentence that says so."""
    if float(table.sample_rate_hz) < MIN_RATE_OVER_PULSE * pulse_hz:
        raise AnalysisError(
            f"step {step.id}: the table log holds {table.sample_rate_hz:g} Hz snapshots, too "
            f"slow to resolve the {pulse_hz:g} Hz freeze-pulse edges: this long record "
            "cannot be synchronised (record it again: the table now logs its full-rate head)")


def streamed_relation(step: PlannedStep, table: SampledLog, pieces: Pieces) -> ClockRelation:
    """The clock relation of a long record from its table log's edges (the head the table's
    buffer held) and the DAQ's edges over the same span, read piece by piece.

    The relation carries the DAQ's time line (``daq_time_fit``) and record span, from which
    :func:`synchronise_streamed` rebuilds the record's sample indices without reading it.
    """
    table_t = np.asarray(table.time_s, dtype=np.float64)
    span_s = float(table_t[-1] - table_t[0]) if table_t.size else 0.0
    scan = scan_daq(pieces(_SYNC_CHANNELS), span_s * (1 + _EDGE_MARGIN_REL) + _EDGE_MARGIN_S)
    edges = scan.edges
    offset0 = None
    if scan.trigger is not None:
        edges = edges[edges >= scan.trigger]
        offset0 = float(table_t[0]) - float(scan.time_s(scan.trigger))
    t_daq = scan.time_s(edges)
    if t_daq.size > 1:
        _edges_resolved(step, table, 1.0 / float(np.median(np.diff(t_daq))))
    relation = edge_relation(step.id, table, scan.rate_hz, t_daq, offset0)
    record = (float(scan.time_s(0)), float(scan.time_s(scan.samples - 1)))
    return replace(relation, daq_time_fit=scan.time_fit, record_span_daq_s=record)


def _scan_of(relation: ClockRelation) -> DaqScan:
    """The DAQ time line a :func:`streamed_relation` carries (no edges, no trigger)."""
    if relation.daq_time_fit is None or relation.record_span_daq_s is None:
        raise AnalysisError("a streamed record's clock relation lacks its DAQ time line")
    intercept, slope = relation.daq_time_fit
    t0, t1 = relation.record_span_daq_s
    samples = round((t1 - t0) / slope) + 1
    return DaqScan(samples, t0 - intercept, relation.daq_time_fit, 1.0 / slope)


def synchronise_streamed(step: PlannedStep, table: SampledLog, pieces: Pieces,
                         relation: ClockRelation | None = None) -> SyncedStep:
    """A long record synchronised: the head both loggers cover on the table's time vector
    (as :func:`~aatest.clocksync.freeze_pulse.synchronise` gives it) and the whole DAQ record
    between the table record's planned start and end, read block by block (``record``).

    ``relation``: the step's :func:`streamed_relation` when already fitted.
    """
    relation = relation if relation is not None else streamed_relation(step, table, pieces)
    scan = _scan_of(relation)
    table_t = np.asarray(table.time_s, dtype=np.float64)
    at_daq = relation.to_daq_s(table_t)
    inside = np.flatnonzero((at_daq >= scan.time_s(0)) & (at_daq <= scan.time_s(scan.samples - 1)))
    if inside.size == 0:
        raise AnalysisError(f"step {step.id}: the DAQ record does not cover the table log")
    keep = slice(int(inside[0]), int(inside[-1]) + 1)
    span_s = step.samples / step.sample_rate_hz
    first, stop = record_span(scan, float(table_t[0]), span_s,
                              lambda t: float(relation.to_daq_s(np.asarray(t))))
    everything = _all_channels(pieces)
    return SyncedStep(
        step=step, time_s=table_t[keep], sample_rate_hz=float(table.sample_rate_hz),
        table={n: np.asarray(v)[keep] for n, v in table.channels.items()},
        daq=HeadChannels(pieces, scan, at_daq[keep], everything, _DIGITAL),
        relation=relation, record=StreamedRecord(pieces, first, stop))


def _all_channels(pieces: Pieces) -> list[str]:
    """The DAQ log's channel names (from its first piece)."""
    for piece in pieces(None):
        return list(piece.channels)
    return []
