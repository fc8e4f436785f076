"""The clock relation of the two loggers and a step synchronised with it (docs/method.md §2).

The records every synchronisation path returns — freeze-pulse edges fitted on one step
(:mod:`aatest.clocksync.freeze_pulse`), a long record whose table log covers its head
(:mod:`aatest.clocksync.streamed`) — and that the edge pairing (:mod:`aatest.clocksync.edges`)
reads.
They live apart from the fitting so that the paths can share them without importing each
other: a streamed record is carried as any :class:`RecordBlocks`.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from aatest.engine.steps import PlannedStep


class RecordBlocks(Protocol):
    """A step's whole DAQ record, read block by block.

    :class:`~aatest.clocksync.streamed.StreamedRecord` is the one in use; typing the field by this
    protocol keeps the records free of the streamed path, which builds on them.
    """

    @property
    def samples(self) -> int:
        """DAQ samples in the record proper."""
        ...

    def blocks(self, channels: Sequence[str]) -> Iterator[dict[str, np.ndarray]]:
        """The record's ``channels`` (those the log has) in consecutive blocks, in order."""
        ...


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
    #: the drift was narrowed inside the edges' range by the sine steps' phase trend (no latch
    #: times; :mod:`aatest.clocksync.phase_trend`)
    phase_trend: bool = False

    @property
    def drift_source(self) -> str:
        """What fixed the drift: latch times, the edges alone, or the edges and the trend."""
        if self.latched:
            return "latch times"
        return "edges + sine phase trend" if self.phase_trend else "edges"

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

    def as_dict(self) -> dict[str, float | int | bool | str]:
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
            "drift_source": self.drift_source,
        }


@dataclass(frozen=True)
class SyncedStep:
    """One step with both loggers on the table's time vector.

    ``table`` holds the table channels (trimmed to the DAQ coverage), ``daq`` the DAQ channels
    resampled onto ``time_s`` (analog channels by cubic spline, digital ones by nearest sample;
    after :func:`~aatest.clocksync.freeze_pulse.synchronise`, each when first read).
    """

    step: PlannedStep
    time_s: np.ndarray
    sample_rate_hz: float
    table: Mapping[str, np.ndarray]
    daq: Mapping[str, np.ndarray]
    relation: ClockRelation
    #: a long record whose table log covers its head only (:mod:`aatest.clocksync.streamed`):
    #: the whole DAQ record, read block by block; ``time_s``/``table``/``daq`` are the head
    record: RecordBlocks | None = None

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
