"""A digest of the bytes a decode of one recorded step reads, equal in a step file and in the
merged recording that copied it.

Why: an analysis made of a step file while the run was still recording
(:mod:`aatest.early.analysis`) may stand for the analysis of the same step in
``recording.mcap`` only when the pass would decode exactly the same bytes there. A step's logs
are decoded from its step record (JSON values: the step, the sample counts, the quantisation,
the log-time span of each log) and from the chunks of the ``/table`` and ``/daq`` channels
that overlap that span (:mod:`aatest.recording.reader`); the merge copies the step record's
values and those chunk records byte for byte (:class:`~aatest.recording.mcap_io.ChunkedWriter`
``copy_chunks``). So the digest covers:

- the SHA-256 of the step record's values (:func:`~aatest.recording.format.record_digest`,
  the digest every block of the step carries and the reader checks);
- for each logger, in file order, every chunk record the reader would read for the step's
  span: its length and the CRC-32 of the whole record as stored (header with the CRC-32 and
  size of the uncompressed data, then the compressed data).

Equal digests mean the same record values (SHA-256) and chunk records equal in number, length,
uncompressed CRC and compressed CRC: two independent 32-bit checks over each chunk, against
the accidental differences that can occur here (a step recorded again on resume, a damaged
copy). Since a decode is a function of those bytes alone, equal digests give equal decoded
logs. The early child may also be handed a step's logs instead of decoding its file
(:mod:`aatest.early.handover`: the arrays a decode gives, bit for bit); its digest is then the
run process's, of the file it has just written those arrays to, so equal digests still give
equal decoded logs. Reading costs one CRC pass over the step's compressed bytes (no
decompression: ≈ 1 ms per MB), a fraction of a decode.
"""

from __future__ import annotations

import hashlib
import struct
from collections.abc import Collection
from pathlib import Path
from typing import IO, Any

from mcap.data_stream import ReadDataStream
from mcap.reader import make_reader
from mcap.records import Metadata
from zlib_ng.zlib_ng import crc32

from aatest.engine.errors import RecordingError
from aatest.recording import format as fmt
from aatest.recording.reader import chunks_overlapping

#: the logger channels a step's decode reads (the preview topics are never decoded)
_SOURCES = ("table", "daq")


def step_digests(path: Path, only: Collection[str] | None = None) -> dict[str, str]:
    """Step id → digest (hex) of every step an aatest MCAP file holds (a step file: one), or
    of those in ``only``.

    Raises
    ------
    RecordingError
        When the file is no complete aatest recording (it has no summary).
    """
    with open(path, "rb") as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        if summary is None:
            raise RecordingError(f"{path}: no summary (an unfinished write)")
        records = [_metadata(stream, ix) for ix in summary.metadata_indexes
                   if ix.name == fmt.STEP_RECORD]  # not the run record: it holds the plan
        ids = [str(fmt.from_json_values(values)["step"]["id"]) for values in records]
        return {step_id: _digest(stream, summary, values)
                for step_id, values in zip(ids, records, strict=True)
                if only is None or step_id in only}


def _metadata(stream: IO[bytes], index: Any) -> dict[str, str]:
    """The values of the metadata record ``index`` points at (after its opcode and length)."""
    stream.seek(index.offset + 1 + 8)
    return dict(Metadata.read(ReadDataStream(stream)).metadata)


def _digest(stream: IO[bytes], summary: Any, values: dict[str, str]) -> str:
    """The digest of one step (module docstring) from its record's values."""
    record = fmt.from_json_values(values)
    digest = hashlib.sha256(fmt.record_digest(values).encode("ascii"))
    for source in _SOURCES:
        span = record.get(f"{source}_log_time_ns") or []
        digest.update(source.encode("ascii"))
        if not span:
            continue
        for index in chunks_overlapping(summary, {fmt.CHANNEL_IDS[source]}, span[0], span[1]):
            stream.seek(index.chunk_start_offset)
            raw = stream.read(index.chunk_length)
            digest.update(struct.pack("<QI", len(raw), crc32(raw)))  # zlib's CRC-32
    return digest.hexdigest()
