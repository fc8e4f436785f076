"""The plottable preview of a recording: named scalar ``double`` fields per 200 ms window.

Why a second view of the same samples: the exact record is the packed ``SampleBlock`` stream
(integer codes as byte planes, :mod:`aatest.recording.codec`), which a generic MCAP viewer
decodes but cannot plot — no field of it is a physical value. So every recording also carries,
per logger, a topic ``/preview/table`` and ``/preview/daq`` whose protobuf messages are one
:data:`WINDOW_S` window each, with one ``double`` field per previewed channel and statistic in
the channel's physical unit (``inner_rate_dps_mean``, ``v_sx_min``, ``temperature_c_max`` …),
the units as JSON in the MCAP channel metadata ``units``. The preview is a view, never the
record: the analyses read only the blocks.

Why every message is built here as fixed-size bytes: a run has 5 windows per lab second per
logger (96 000 messages for the shipped stepped-sine campaign); building them one by one
through the protobuf API would take longer than recording the run. Every field is a fixed-width
protobuf scalar (``fixed32`` or ``double``, always written, also when 0), so a message and its
MCAP ``Message`` record have one layout and a whole chunk is one NumPy structured array
(:func:`message_records`). The bytes are exactly what protobuf serialises for the same values
with every field present; a test decodes them with protobuf's ``message_factory`` alone.

The ``.proto`` of the DAQ preview of a rig with sensors ``v_sx`` and ``v_sz``::

    syntax = "proto3";
    package aatest.preview.v1;
    message Daq {
      fixed32 step_index = 1;      // 1-based plan position of the step
      double time_s = 2;           // the logger's own time of the window's first sample, s
      double v_sx_min = 3;         // per previewed channel: min, max, mean of the window
      double v_sx_max = 4;
      double v_sx_mean = 5;
      ...
    }
"""

from __future__ import annotations

import json
import re
import zlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import cache, cached_property

import numpy as np
from google.protobuf import descriptor_pb2
from mcap.records import Channel, Schema

from aatest.engine.logs import TABLE, SampledLog
from aatest.recording import proto
from aatest.recording.channels import CHUNK_BYTES

#: length of one preview window, s (a 2 kHz logger: 400 samples per window). Why not 10 ms:
#: the preview's doubles hardly compress and MCAP indexes every message with 16 bytes
#: uncompressed, so 10 ms windows made a stepped-sine recording 84 % larger; 100 ms added
#: 8.3 % (stepped sine) and 11.2 % (a 10-min static record); 200 ms adds 4.1 % and 6.5 %
#: (``bench/recording.py`` prints the share)
WINDOW_S = 0.2
PACKAGE = "aatest.preview.v1"
#: the statistics of every previewed channel, in field order
STATISTICS = ("min", "max", "mean")
#: table channels a viewer plots (their suffix is the unit); the DAQ's are its sensors and
#: temperature
TABLE_PREVIEW = tuple(f"{axis}_{quantity}" for axis in ("inner", "outer")
                      for quantity in ("position_deg", "rate_dps", "accel_dps2"))
DAQ_PREVIEW_AUX = ("temperature_c",)
#: MCAP ids of preview channels start here (ids 1 and 2 are the block channels); the id is
#: derived from the field list, so steps of one rig share one channel per topic
FIRST_CHANNEL_ID = 16
_ID_SLOTS = 30_000
_OPCODE_MESSAGE = 0x05
_WIRE_FIXED64, _WIRE_FIXED32 = 1, 5
_F = descriptor_pb2.FieldDescriptorProto


def topic(source: str) -> str:
    """``/preview/table`` or ``/preview/daq``."""
    return f"/preview/{source}"


def previewed_channels(log: SampledLog) -> list[str]:
    """The channels of ``log`` a viewer plots: table motion, DAQ sensor volts and temperature."""
    wanted = TABLE_PREVIEW if log.source == TABLE else (*log.sensor_channels(), *DAQ_PREVIEW_AUX)
    return [name for name in wanted if name in log.channels]


def window_samples(sample_rate_hz: float) -> int:
    """Samples per window: ``round(WINDOW_S · rate)``, at least 1 (slow loggers: every sample).

    ``sample_rate_hz`` is the logger's rate in Hz.
    """
    return max(1, round(WINDOW_S * float(sample_rate_hz)))


@cache  # a few channel names per rig; called for every window run (a regex each)
def _field_name(channel: str, statistic: str) -> str:
    return re.sub(r"[^A-Za-z0-9_]", "_", f"{channel}_{statistic}")


@dataclass(frozen=True)
class Layout:
    """The preview message of one logger with a given channel list, and its byte layout."""

    source: str
    channels: tuple[str, ...]
    units: tuple[str, ...]

    @property
    def message_name(self) -> str:
        """Full protobuf name of the logger's preview message (``aatest.preview.v1.Table``)."""
        return f"{PACKAGE}.{self.source.capitalize()}"

    @property
    def fields(self) -> list[str]:
        """Field names from number 3 on (1 = step_index, 2 = time_s)."""
        return [_field_name(c, s) for c in self.channels for s in STATISTICS]

    @cached_property  # read for every chunk of preview records
    def channel_id(self) -> int:
        """MCAP channel id: a stable slot from the logger and its channel list, odd for the
        DAQ and even for the table, above the exact blocks' channel ids."""
        key = json.dumps([self.source, self.channels]).encode("utf-8")
        slot = zlib.crc32(key) % _ID_SLOTS
        return FIRST_CHANNEL_ID + 2 * slot + (0 if self.source == TABLE else 1)

    @cache  # noqa: B019 - a handful of layouts per process; frozen and hashable
    def schema_data(self) -> bytes:
        """The serialised ``FileDescriptorSet`` of the message (MCAP schema encoding protobuf)."""
        file = descriptor_pb2.FileDescriptorProto(
            name=f"aatest/preview/v1/{self.source}_{self.channel_id}.proto", package=PACKAGE,
            syntax="proto3")
        message = file.message_type.add(name=self.source.capitalize())
        message.field.add(name="step_index", number=1, type=_F.TYPE_FIXED32,
                          label=_F.LABEL_OPTIONAL)
        message.field.add(name="time_s", number=2, type=_F.TYPE_DOUBLE, label=_F.LABEL_OPTIONAL)
        for number, name in enumerate(self.fields, start=3):
            message.field.add(name=name, number=number, type=_F.TYPE_DOUBLE,
                              label=_F.LABEL_OPTIONAL)
        descriptor_set = descriptor_pb2.FileDescriptorSet()
        descriptor_set.file.append(file)
        return descriptor_set.SerializeToString(deterministic=True)

    def mcap_channel(self, schema_id: int) -> Channel:
        """The MCAP channel record: topic, protobuf encoding, and units in its metadata."""
        units = {"time_s": "s"} | {
            _field_name(c, s): unit for c, unit in zip(self.channels, self.units, strict=True)
            for s in STATISTICS}
        return Channel(id=self.channel_id, topic=topic(self.source), message_encoding="protobuf",
                       schema_id=schema_id, metadata={
                           "source": self.source, "units": json.dumps(units, sort_keys=True),
                           "window_s": repr(WINDOW_S),
                           "statistics": "min, max and mean of the samples in each window",
                       })

    def mcap_schema(self, schema_id: int) -> Schema:
        """The MCAP schema record: the message's ``FileDescriptorSet`` (encoding protobuf)."""
        return Schema(id=schema_id, name=self.message_name, encoding="protobuf",
                      data=self.schema_data())

    @cache  # noqa: B019 - a handful of layouts per process; frozen and hashable
    def record_dtype(self) -> np.dtype:
        """One MCAP ``Message`` record holding one preview message, as a packed struct."""
        parts: list[tuple[str, str]] = [
            ("opcode", "u1"), ("length", "<u8"), ("channel_id", "<u2"), ("sequence", "<u4"),
            ("log_time", "<u8"), ("publish_time", "<u8"),
            ("tag_1", "u1"), ("step_index", "<u4"), ("tag_2", "u1"), ("time_s", "<f8")]
        for number, _ in enumerate(self.fields, start=3):
            width = len(proto.varint((number << 3) | _WIRE_FIXED64))
            parts += [(f"tag_{number}", f"({width},)u1"), (f"f_{number}", "<f8")]
        return np.dtype(parts)


def layout_of(log: SampledLog) -> Layout:
    """The preview layout of a logger's log."""
    channels = tuple(previewed_channels(log))
    return Layout(log.source, channels, tuple(str(log.units.get(c, "")) for c in channels))


@dataclass(frozen=True)
class Windows:
    """Statistics of consecutive whole windows: time of each window's first sample and, per
    field, one value per window."""

    time_s: np.ndarray
    values: Mapping[str, np.ndarray]


@dataclass(frozen=True)
class Samples:
    """Consecutive samples of a logger's previewed channels: views of its log, or of a window
    carried over between chunks (a :class:`SampledLog` would copy its time stamps each time)."""

    time_s: np.ndarray
    channels: Mapping[str, np.ndarray]

    def __len__(self) -> int:
        return int(self.time_s.shape[0])

    def part(self, start: int, stop: int) -> Samples:
        """Samples ``start … stop − 1`` (views)."""
        return Samples(self.time_s[start:stop],
                       {k: v[start:stop] for k, v in self.channels.items()})


def windows(log: SampledLog | Samples, layout: Layout, per_window: int) -> Windows:
    """Min, max and mean of every window of ``per_window`` samples (a short last one too)."""
    n = len(log)
    starts = np.arange(0, n, per_window, dtype=np.intp)
    values: dict[str, np.ndarray] = {}
    counts = np.diff(starts, append=n)
    for channel in layout.channels:
        data = np.asarray(log.channels[channel], dtype=np.float64)
        values[_field_name(channel, "min")] = np.minimum.reduceat(data, starts)
        values[_field_name(channel, "max")] = np.maximum.reduceat(data, starts)
        values[_field_name(channel, "mean")] = np.add.reduceat(data, starts) / counts
    return Windows(np.asarray(log.time_s[starts], dtype=np.float64), values)


def message_records(layout: Layout, step_index: int, stats: Windows, log_times_ns: np.ndarray,
                    first_sequence: int) -> bytes:
    """The MCAP ``Message`` records of a run of windows, as one byte string (a chunk's data).

    ``log_times_ns`` are the windows' log times in ns on the run's UTC time line.
    """
    dtype = layout.record_dtype()
    records = np.zeros(len(stats.time_s), dtype=dtype)
    records["opcode"] = _OPCODE_MESSAGE
    records["length"] = dtype.itemsize - 9
    records["channel_id"] = layout.channel_id
    records["sequence"] = (first_sequence + np.arange(len(records))) % 2**32
    records["log_time"] = log_times_ns
    records["publish_time"] = log_times_ns
    records["tag_1"] = (1 << 3) | _WIRE_FIXED32
    records["step_index"] = step_index
    records["tag_2"] = (2 << 3) | _WIRE_FIXED64
    records["time_s"] = stats.time_s
    for number, name in enumerate(layout.fields, start=3):
        records[f"tag_{number}"] = np.frombuffer(proto.varint((number << 3) | _WIRE_FIXED64), "u1")
        records[f"f_{number}"] = stats.values[name]
    return records.tobytes()


def log_times_ns(time_s: np.ndarray, start_ns: int, floor_ns: int) -> np.ndarray:
    """Log time of each window: ``start_ns`` + its first sample's time, never below ``floor_ns``.

    ``time_s`` are the windows' first-sample times in s on the logger's clock; ``start_ns``
    (the run's start) and ``floor_ns`` are in ns; the log times returned are in ns.
    """
    times = start_ns + np.round(np.asarray(time_s, dtype=np.float64) * 1e9).astype(np.int64)
    return np.maximum(times, floor_ns).astype(np.uint64)


def records_per_chunk(layout: Layout) -> int:
    """Preview messages per MCAP chunk (about :data:`CHUNK_BYTES`)."""
    return max(1, CHUNK_BYTES // layout.record_dtype().itemsize)


class PreviewStream:
    """Windows one logger's log as it arrives (whole log or chunks) into preview records.

    ``sink(layout, records, log_times_ns)`` receives each run of whole windows (ready MCAP
    ``Message`` records, at most :data:`CHUNK_BYTES`); samples of an unfinished window are
    carried to the next :meth:`add`, and :meth:`finish` emits the last, short window.
    ``start_ns`` is the log time of the logger's time 0 (run epoch + step origin + margin),
    ``floor_ns`` the step's origin (no window is logged before it).
    """

    def __init__(self, step_index: int, start_ns: int, floor_ns: int,
                 sink: Callable[[Layout, bytes, np.ndarray], None]) -> None:
        self._step_index, self._start_ns, self._floor_ns = step_index, start_ns, floor_ns
        self._sink = sink
        self._carry: Samples | None = None
        self._sequence = 0
        self.layout: Layout | None = None

    def add(self, log: SampledLog, last: bool = False) -> None:
        """Take the next samples; emit every window they complete (with ``last``: every
        window, the short last one too, as :meth:`finish` would, in one pass)."""
        if len(log) == 0:
            if last:
                self.finish()
            return
        if self.layout is None:
            self.layout = layout_of(log)
        samples = Samples(log.time_s, {c: log.channels[c] for c in self.layout.channels})
        joined = samples if self._carry is None else _join(self._carry, samples)
        per_window = window_samples(log.sample_rate_hz)
        if last:  # windows() takes a short last window as finish() does: same values
            self._emit(joined, per_window)
            self._carry = None
            return
        whole = len(joined) // per_window * per_window
        if whole:
            self._emit(joined.part(0, whole), per_window)
        self._carry = joined.part(whole, len(joined)) if whole < len(joined) else None

    def finish(self) -> None:
        """Emit the short last window, if any."""
        if self._carry is not None:
            self._emit(self._carry, len(self._carry))
            self._carry = None

    def _emit(self, samples: Samples, per_window: int) -> None:
        layout = self.layout
        if layout is None or not layout.channels:
            return
        per_chunk = records_per_chunk(layout) * per_window
        for first in range(0, len(samples), per_chunk):
            stats = windows(samples.part(first, min(len(samples), first + per_chunk)), layout,
                            per_window)
            times = log_times_ns(stats.time_s, self._start_ns, self._floor_ns)
            self._sink(layout, message_records(layout, self._step_index, stats, times,
                                               self._sequence), times)
            self._sequence += len(times)


def _join(first: Samples, second: Samples) -> Samples:
    return Samples(np.concatenate([first.time_s, second.time_s]),
                   {k: np.concatenate([v, second.channels[k]]) for k, v in first.channels.items()})
