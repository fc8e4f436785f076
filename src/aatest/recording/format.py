"""The aatest recording format (MCAP), version 3: constants, topics and log times.

A recording is a standard MCAP file (https://mcap.dev) with zstd-compressed chunks whose
messages are protobuf with the schema embedded, so any MCAP reader or viewer (Python, C++, Go,
TypeScript ``@mcap/core``, the ``mcap`` CLI, Foxglove) opens and decodes it. What a viewer
*plots* is the preview topics (below): the sample blocks hold their values as packed integer
codes, which a generic viewer decodes but cannot turn into physical values. Everything needed
to decode it is in the file itself:

**Header.** ``profile = "aatest"``.

**Metadata records** (MCAP ``Metadata``, values are strings; every value is JSON text):

- ``"run"`` (once): keys as given by the runner, e.g. ``procedure`` (name),
  ``procedure_text``, ``procedure_sha256``, ``rig``, ``plugin_versions``, ``seed``,
  ``sensors`` (list of :class:`~aatest.recording.dataset.SensorInfo` dicts), ``plan`` (list of
  planned steps), ``aatest_version``, ``started_utc``; plus ``format`` =
  ``"aatest.recording/v3"``.
- ``"step"`` (one per recorded step, in plan order): ``step`` (the
  :class:`~aatest.engine.steps.PlannedStep` as JSON), ``index`` (1-based position in the plan),
  ``extra``, and per logger (``table_…``/``daq_…``): ``_topic``, ``_sample_rate_hz``,
  ``_samples``, ``_log_time_ns`` (``[first, last]`` log time of its blocks) and
  ``_quantisation`` (the logger's declared ``{channel: [quantum, offset]}``).

**Channels.** Two stable topics for the whole run, ``/table`` (channel id 1) and ``/daq``
(channel id 2), message encoding ``protobuf``, channel metadata ``source``. Each chunk holds
messages of one step and one topic, so per-step files merge without re-encoding.

**Schema.** One schema, id 1, name ``aatest.recording.v2.SampleBlock``, encoding ``protobuf``,
data the serialised ``FileDescriptorSet`` (:mod:`aatest.recording.proto` prints the
``.proto``).

**Messages.** Each message is one ``SampleBlock``: up to :data:`BLOCK_SAMPLES` (4096)
consecutive samples of *all* channels of one logger in one step, with ``step_id``,
``step_index``, ``sequence`` (block number in the step's log), ``first_sample``, the time stamps
(``time``) and one ``Channel`` per logged channel. A channel's samples are either packed float64
``values`` or integer codes (their running sum when ``delta`` is set) with
``value = code·quantum + offset`` (float64); the codes are ``packed`` little-endian integers of
``width`` bytes, as byte planes when ``shuffled``. Codes are used
only where that reproduces every logged value bit for bit (ADC codes, encoder counts, 0/1
pulses; a −0.0 returns as +0.0; :mod:`aatest.recording.codec`); ``dtype`` restores the
logged NumPy dtype.
Concatenating a step's blocks in ``sequence`` order gives its log; ``step_record_sha256`` in
every block is the SHA-256 of the step's metadata record (values as a JSON object with sorted
keys and no spaces) — MCAP protects chunks with CRCs but not metadata.

**Preview** (:mod:`aatest.recording.preview`). Per logger a topic ``/preview/table`` and
``/preview/daq`` (channel ids from 16, schemas ``aatest.preview.v1.Table`` and ``.Daq``, one
per channel list): one message per :data:`~aatest.recording.preview.WINDOW_S` (200 ms)
window of a step's samples, with ``step_index``, ``time_s`` (the logger's time of the window's
first sample) and ``<channel>_min``, ``_max``, ``_mean`` as scalar ``double`` in physical units
for the table's ``inner_``/``outer_`` ``position_deg``, ``rate_dps``, ``accel_dps2`` and the
DAQ's sensor volts (``v_*``) and ``temperature_c``; the channel metadata ``units`` (JSON) names
each field's unit. Its log time is that of its first sample (as for blocks). The preview is a
view of the blocks, never read by aatest's analyses.

**Log times** (integer ns) lay the steps out on the run's UTC time line so a viewer shows the
calendar time: the run starts at ``started_utc`` of the run record (whole seconds; 0 when the
record has none, as in recordings written before the preview), and
step *k* starts ``origin_k = Σ_{j<k} ceil(duration_j + 2·STEP_MARGIN_S)`` s later (durations from
the run's ``plan``; :data:`UNPLANNED_STEP_S` for a step not in it), and a block's ``log_time``
is ``origin_k + STEP_MARGIN_S + time_s[first sample]`` (each logger's own clock, so the DAQ's
lead before the trigger stays positive), never below ``origin_k``. The exact times are always
the ``time`` channel.

Older recordings are still read: format v2 (the same layout, with the codes as protobuf
varints in the ``codes`` field; :data:`FORMAT_V2`) and v1 (``aatest.block/v1``, one topic per
step: :mod:`aatest.recording.legacy_v1`).
"""

from __future__ import annotations

import hashlib
import json
import math
import struct
from collections.abc import Sequence
from datetime import UTC, datetime
from typing import Any

import numpy as np
import zstandard
from mcap.exceptions import McapError

FORMAT = "aatest.recording/v3"
#: the previous format (codes as varints): read by the same decoder
FORMAT_V2 = "aatest.recording/v2"
PROFILE = "aatest"
ENCODING = "protobuf"
BLOCK_SAMPLES = 4096
#: seconds before and after each step on the run time line (covers the DAQ's lead and lag)
STEP_MARGIN_S = 5
#: time-line slot of a step the plan does not list, in s
UNPLANNED_STEP_S = 3600
#: MCAP ids: the one schema, and the two stable channels
SCHEMA_ID = 1
CHANNEL_IDS = {"table": 1, "daq": 2}
RUN_RECORD = "run"
STEP_RECORD = "step"


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


def topic(source: str) -> str:
    """MCAP topic of one logger's blocks for the whole run: ``/table`` or ``/daq``."""
    return f"/{source}"


def step_origin_ns(plan: Sequence[Any] | None, index: int) -> int:
    """Run time-line start of the step at 1-based plan position ``index``, in integer ns."""
    entries = list(plan or [])
    total_s = 0
    for position in range(1, index):
        entry = entries[position - 1] if position <= len(entries) else None
        duration = entry.get("duration_s") if isinstance(entry, dict) else None
        span = float(duration) if isinstance(duration, (int, float)) else UNPLANNED_STEP_S
        total_s += math.ceil(span + 2 * STEP_MARGIN_S)
    return total_s * 1_000_000_000


def run_epoch_ns(run_meta: dict[str, Any] | None) -> int:
    """UTC start of the run (``started_utc`` of the run record) in ns since 1970, else 0.

    Every log time is laid out from it, so a viewer shows the calendar time of the samples;
    a run record without a readable ``started_utc`` keeps the relative time line (from 0).
    """
    text = (run_meta or {}).get("started_utc")
    try:
        started = datetime.fromisoformat(str(text))
    except ValueError:
        return 0
    if started.tzinfo is None:
        started = started.replace(tzinfo=UTC)
    return max(0, round(started.timestamp())) * 1_000_000_000


def step_start_ns(run_meta: dict[str, Any] | None, index: int) -> int:
    """Origin of the step at plan position ``index`` on the run's UTC time line, ns."""
    return run_epoch_ns(run_meta) + step_origin_ns((run_meta or {}).get("plan"), index)


def block_log_times_ns(time_s: np.ndarray, origin_ns: int, block_samples: int) -> list[int]:
    """Log time of every block's first sample on the run time line, in integer ns.

    ``time_s`` are the logger's sample times in s, ``origin_ns`` the step's origin
    (:func:`step_origin_ns`).
    """
    firsts = np.asarray(time_s[::block_samples], dtype=np.float64)
    start_ns = origin_ns + STEP_MARGIN_S * 1_000_000_000
    return [max(origin_ns, start_ns + round(t * 1e9)) for t in firsts.tolist()]


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
