"""The aatest recording format (MCAP), version 1: constants and the sample-block codec.

A recording is a standard MCAP file (https://mcap.dev) with zstd-compressed chunks, so the
plain ``mcap`` reader (Python, C++, Go, the ``mcap`` CLI, Foxglove) opens it. Everything needed
to decode it is in the file itself:

**Header.** ``profile = "aatest"``.

**Metadata records** (MCAP ``Metadata``, values are strings; every value is JSON text):

- ``"run"`` (once): keys as given by the runner, e.g. ``procedure`` (name),
  ``procedure_text``, ``procedure_sha256``, ``rig``, ``plugin_versions``, ``seed``,
  ``sensors`` (list of :class:`~aatest.engine.dataset.SensorInfo` dicts), ``plan`` (list of
  planned steps), ``aatest_version``, ``started_utc``; plus ``format`` =
  ``"aatest.recording/v1"``.
- ``"step"`` (one per recorded step, in plan order): ``step`` (the
  :class:`~aatest.engine.steps.PlannedStep` as JSON), ``index`` (1-based position in the plan),
  ``table_topic``/``daq_topic``, ``table_sample_rate_hz``/``daq_sample_rate_hz``, ``extra``.

**Channels.** Per step two topics, ``/<step_id>/table`` and ``/<step_id>/daq``; channel
metadata ``step_id``, ``source`` (``table``/``daq``), ``samples`` (total samples of the log) and
``log_time_offset_ns`` (see below) and ``step_record_sha256``, the SHA-256 of the step's
``step`` metadata record (its values as a JSON object with sorted keys and no spaces) — MCAP
protects chunks with CRCs but not metadata, so a reader can tell a damaged step record from a
good one; likewise ``schema_sha256`` of the channel's schema data. Channel ids are
``2·index − 1`` (table) and ``2·index`` (DAQ), ``index`` being the step's 1-based plan
position, so they are unique in a run and the per-step files merge without re-encoding.
Each chunk holds messages of one channel only.

**Schemas.** name ``aatest.table_block`` / ``aatest.daq_block``, encoding ``aatest.block/v1``.
The schema data is UTF-8 JSON::

    {"columns": [{"name": "time_s", "dtype": "<f8", "unit": "s"}, ...],
     "source": "table", "sample_rate_hz": 2000.0}

``dtype`` is a NumPy dtype string, always little-endian (``<f8``, ``<f4``, ``|u1``, ...): time
and table channels are ``<f8``; ``sync_pulse`` and ``trigger`` are ``|u1`` (0/1); DAQ volts and
temperature keep the logger's own dtype (``<f8`` or ``<f4``).

**Messages.** Message encoding ``aatest.block/v1``. Each message is one block of up to
:data:`BLOCK_SAMPLES` (4096) consecutive samples of *all* channels of one logger, as a packed
(no padding) array of records in column order; decode with::

    dtype = np.dtype([(c["name"], c["dtype"]) for c in json.loads(schema.data)["columns"]])
    block = np.frombuffer(message.data, dtype=dtype)

``sequence`` is the block number (0, 1, ...) within the step's log; concatenating the blocks
in sequence order gives the log. ``log_time`` and ``publish_time`` are the integer nanoseconds
of the block's first sample on *that logger's own clock* (the clocks are not synchronised),
shifted by the channel's ``log_time_offset_ns``: ``log_time = round(time_s·1e9) +
log_time_offset_ns``. The offset is 0 unless a logger's clock starts before zero (the DAQ starts
before the trigger), in which case it is the smallest whole number of nanoseconds that makes
every log time non-negative. The exact times are always the ``time_s`` column.
"""

from __future__ import annotations

import hashlib
import json
import math
import struct
from typing import Any

import numpy as np
import zstandard
from mcap.exceptions import McapError

from aatest.engine.logs import DAQ_AUX_CHANNELS, TABLE_CHANNELS, SampledLog

FORMAT = "aatest.recording/v1"
PROFILE = "aatest"
ENCODING = "aatest.block/v1"
BLOCK_SAMPLES = 4096
RUN_RECORD = "run"
STEP_RECORD = "step"
TIME_COLUMN = "time_s"
#: channels stored as 0/1 bytes when their values allow it
_BINARY_CHANNELS = ("sync_pulse", "trigger")
_ALLOWED_KINDS = "fiub"


#: what a damaged or foreign file can make the mcap/zstd/json layers raise
DECODE_ERRORS: tuple[type[BaseException], ...] = (
    McapError,
    struct.error,
    zstandard.ZstdError,
    ValueError,
    KeyError,
    TypeError,
    IndexError,
    EOFError,
    OSError,
    MemoryError,
)


def schema_name(source: str) -> str:
    """MCAP schema name of one logger's block schema."""
    return f"aatest.{source}_block"


def topic(step_id: str, source: str) -> str:
    """MCAP topic of one step's log from one logger."""
    return f"/{step_id}/{source}"


def _unit(log: SampledLog, name: str) -> str:
    if name in log.units:
        return str(log.units[name])
    known = {**TABLE_CHANNELS, **DAQ_AUX_CHANNELS}
    return known.get(name, "V" if name.startswith("v_") else "")


def _storage(name: str, values: np.ndarray) -> np.ndarray:
    """The array as stored: little-endian, 0/1 pulse channels as uint8."""
    arr = np.asarray(values)
    if arr.dtype.kind not in _ALLOWED_KINDS:
        raise TypeError(f"channel {name!r} has unsupported dtype {arr.dtype}")
    is_pulse = name in _BINARY_CHANNELS and arr.dtype != np.uint8
    if is_pulse and (arr.size == 0 or bool(np.all((arr == 0) | (arr == 1)))):
        return arr.astype(np.uint8)
    return arr.astype(arr.dtype.newbyteorder("<"), copy=False)


def log_records(log: SampledLog) -> tuple[np.ndarray, list[dict[str, str]]]:
    """Pack a log into one structured array (``time_s`` first) and its column descriptions."""
    if TIME_COLUMN in log.channels:
        raise ValueError(f"{log.source} log has a channel named {TIME_COLUMN!r}")
    arrays = {TIME_COLUMN: np.asarray(log.time_s, dtype="<f8")}
    arrays.update({name: _storage(name, values) for name, values in log.channels.items()})
    dtype = np.dtype([(name, arr.dtype.str) for name, arr in arrays.items()])
    records = np.empty(len(log), dtype=dtype)
    for name, arr in arrays.items():
        records[name] = arr
    columns = [
        {"name": name, "dtype": arr.dtype.str,
         "unit": "s" if name == TIME_COLUMN else _unit(log, name)}
        for name, arr in arrays.items()
    ]
    return records, columns


def schema_data(log: SampledLog, columns: list[dict[str, str]]) -> bytes:
    """The JSON schema document of a log's block schema."""
    doc = {"columns": columns, "source": log.source, "sample_rate_hz": float(log.sample_rate_hz)}
    return json.dumps(doc, sort_keys=True).encode("utf-8")


def log_time_offset_ns(time_s: np.ndarray) -> int:
    """Smallest non-negative offset making every ``round(t·1e9) + offset`` non-negative.

    ``time_s`` are sample times in s; the offset is in integer ns.
    """
    if time_s.size == 0:
        return 0
    first = float(np.min(time_s))
    return 0 if first >= 0 else math.ceil(-first * 1e9)


def block_log_times_ns(time_s: np.ndarray, offset_ns: int) -> list[int]:
    """Log time of every block's first sample, in integer nanoseconds.

    ``time_s`` are the sample times in s, ``offset_ns`` the run's log-time offset in ns.
    """
    firsts = np.asarray(time_s[::BLOCK_SAMPLES], dtype=np.float64)
    return [max(0, round(t * 1e9) + offset_ns) for t in firsts.tolist()]


def parse_schema(data: bytes) -> tuple[np.dtype, dict[str, Any]]:
    """Decode a block schema → (record dtype, schema document); ValueError if malformed."""
    doc = json.loads(data.decode("utf-8"))
    if not isinstance(doc, dict) or not isinstance(doc.get("columns"), list):
        raise ValueError("schema has no column list")
    fields = []
    for col in doc["columns"]:
        dtype = np.dtype(str(col["dtype"]))
        if dtype.kind not in _ALLOWED_KINDS or dtype.byteorder == ">":
            raise ValueError(f"column {col['name']!r} has unsupported dtype {dtype}")
        fields.append((str(col["name"]), dtype.str))
    if not fields or fields[0][0] != TIME_COLUMN:
        raise ValueError(f"first column must be {TIME_COLUMN!r}")
    return np.dtype(fields), doc


def _frozen_column(records: np.ndarray, name: str) -> np.ndarray:
    """A contiguous read-only copy of one column (SampledLog then keeps it without copying)."""
    column = np.array(records[name], copy=True)
    column.flags.writeable = False
    return column


def records_to_log(records: np.ndarray, doc: dict[str, Any]) -> SampledLog:
    """Rebuild a :class:`SampledLog` from the concatenated records of one step's log."""
    units = {str(c["name"]): str(c.get("unit", "")) for c in doc["columns"][1:]}
    channels = {name: _frozen_column(records, name) for name in units}
    return SampledLog(
        source=str(doc.get("source", "")),
        sample_rate_hz=float(doc["sample_rate_hz"]),
        time_s=np.ascontiguousarray(records[TIME_COLUMN]),
        channels=channels,
        units=units,
    )


def json_values(meta: dict[str, Any]) -> dict[str, str]:
    """MCAP metadata values are strings: store every value as JSON text."""
    return {str(k): json.dumps(v, sort_keys=True, default=_json_default) for k, v in meta.items()}


def record_digest(values: dict[str, str]) -> str:
    """SHA-256 of a metadata record's string values: MCAP metadata has no CRC of its own."""
    canonical = json.dumps(values, sort_keys=True, separators=(",", ":")).encode("utf-8")
    return hashlib.sha256(canonical).hexdigest()


def from_json_values(data: dict[str, str]) -> dict[str, Any]:
    """Inverse of :func:`json_values`."""
    return {k: json.loads(v) for k, v in data.items()}


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if hasattr(value, "model_dump"):
        return value.model_dump(mode="json")
    if hasattr(value, "__dataclass_fields__"):
        return {k: getattr(value, k) for k in value.__dataclass_fields__}
    return str(value)
