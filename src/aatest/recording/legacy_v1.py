"""Reading recordings of format v1 (``aatest.block/v1``): kept so older recordings still load.

Format v1 (aatest < 0.3) stored each step on its own topics ``/<step_id>/table`` and
``/<step_id>/daq``, schema encoding ``aatest.block/v1`` with a JSON schema
``{"columns": [{"name", "dtype", "unit"}, ...], "source", "sample_rate_hz"}``, and each message a
packed little-endian NumPy record array of up to 4096 samples of every column (``time_s``
first); ``sequence`` numbers the blocks. Only the decoding half lives here; the writer is gone.
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np

from aatest.engine.logs import SampledLog

FORMAT_V1 = "aatest.recording/v1"
ENCODING_V1 = "aatest.block/v1"
TIME_COLUMN = "time_s"
_ALLOWED_KINDS = "fiub"


def parse_schema(data: bytes) -> tuple[np.dtype, dict[str, Any]]:
    """Decode a v1 block schema → (record dtype, schema document); ValueError if malformed."""
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
    """Rebuild a :class:`SampledLog` from the concatenated v1 records of one step's log."""
    units = {str(c["name"]): str(c.get("unit", "")) for c in doc["columns"][1:]}
    channels = {name: _frozen_column(records, name) for name in units}
    return SampledLog(
        source=str(doc.get("source", "")),
        sample_rate_hz=float(doc["sample_rate_hz"]),
        time_s=np.ascontiguousarray(records[TIME_COLUMN]),
        channels=channels,
        units=units,
    )


def decode_log(payloads: list[bytes], schema_data: bytes, samples: int | None) -> SampledLog:
    """One step's log from its v1 block payloads in sequence order.

    Raises
    ------
    ValueError
        A partial sample block, a sample count that disagrees with ``samples``, or a bad schema.
    """
    dtype, doc = parse_schema(schema_data)
    payload = b"".join(payloads)
    if len(payload) % dtype.itemsize:
        raise ValueError("holds a partial sample block")
    records = np.frombuffer(payload, dtype=dtype)
    if samples is not None and len(records) != samples:
        raise ValueError(f"has {len(records)} samples, its channel says {samples}")
    return records_to_log(records, doc)
