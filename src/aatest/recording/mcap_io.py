"""A small MCAP writer with caller-chosen ids and verbatim chunk copying.

Why not only ``mcap.writer.Writer``: it numbers schemas and channels itself (1, 2, ... in every
file), so step files cannot be merged without decompressing, re-parsing and recompressing every
chunk — about 15 s of CPU for a 140-step run. Here each step file gets channel ids unique in the
run (derived from the step's plan index), so :meth:`ChunkedWriter.copy_chunks` merges step files
by copying their compressed chunk and message-index records byte for byte and shifting the
offsets in the chunk indexes; only the small summary is rebuilt. The output is standard MCAP
(schemas and channels in the data section and repeated in the summary, zstd chunks with CRCs,
message/chunk/metadata indexes, statistics, summary offsets) read by any MCAP reader.
"""

from __future__ import annotations

import dataclasses
import struct
from collections.abc import Iterable, Sequence
from itertools import chain
from typing import IO, Any

import numpy as np
import zstandard
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (
    Channel,
    Chunk,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    McapRecord,
    Message,
    MessageIndex,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)
from zlib_ng.zlib_ng import crc32

MAGIC = struct.pack("<8B", 137, 77, 67, 65, 80, 48, 13, 10)
#: zstd level of the chunks. Why 1, not zstd's default 3: on the delta-coded sample blocks it
#: compresses ~3.4x faster (≈600 vs 180 MB/s) for a 7 % larger file (ratio 0.39 vs 0.36), and
#: compression was a tenth of the CPU time of recording a run; any level decodes the same way
COMPRESSION_LEVEL = 1
#: a ``Message`` record's opcode, length, channel id, sequence, log and publish time; the
#: length counts the fields after it (2 + 4 + 8 + 8 bytes) and the data
_MESSAGE_HEAD = struct.Struct("<BQHIQQ")
_MESSAGE_FIELDS = 22
#: a ``Chunk`` record up to its compression name: opcode, length, start and end time,
#: uncompressed size and CRC, the name's length; the length counts 8 + 8 + 8 + 4 + 4 bytes,
#: the name, the data's 8-byte length and the data
_CHUNK_HEAD = struct.Struct("<BQQQQII")
_CHUNK_FIELDS = 40
#: a ``MessageIndex`` record up to its entries: opcode, length, channel id, the entries'
#: length in bytes; the length counts 2 + 4 bytes and the entries (16 bytes each)
_INDEX_HEAD = struct.Struct("<BQHI")
_INDEX_FIELDS = 6

# Why zlib-ng's crc32, not zlib's: the same CRC-32 (a fixed function of the bytes), computed
# ≈ 6× faster (folding with carry-less multiplication): ≈ 1 ms less CPU per step file of the
# stepped sine, whose chunks hold 5 MB of messages a step (bench/step_writer.py)


def _message_index(channel_id: int, entries: Sequence[tuple[int, int]]) -> bytes:
    """A ``MessageIndex`` record as ``MessageIndex.write`` lays it out, packed in one
    ``struct`` call (``entries``: each message's log time in ns and offset in the chunk)."""
    size = 16 * len(entries)
    return struct.pack(f"<BQHI{2 * len(entries)}Q", Opcode.MESSAGE_INDEX, _INDEX_FIELDS + size,
                       channel_id, size, *chain.from_iterable(entries))


class ChunkedWriter:
    """Write one MCAP file: records go straight to ``stream``; the summary is kept in memory.

    Parameters
    ----------
    stream
        A binary stream positioned at 0 (a fresh file).
    profile, library
        Header fields.
    """

    def __init__(self, stream: IO[bytes], profile: str, library: str) -> None:
        self._stream = stream
        self._offset = 0
        self._compressor = zstandard.ZstdCompressor(level=COMPRESSION_LEVEL)
        self.schemas: dict[int, Schema] = {}
        self.channels: dict[int, Channel] = {}
        self._chunk_indexes: list[ChunkIndex] = []
        self._metadata_indexes: list[MetadataIndex] = []
        self.stats = Statistics(
            attachment_count=0, channel_count=0, channel_message_counts={}, chunk_count=0,
            message_count=0, message_end_time=0, message_start_time=0, metadata_count=0,
            schema_count=0,
        )
        self._write_bytes(MAGIC)
        self._write(Header(profile=profile, library=library))

    def _write_bytes(self, data: bytes) -> int:
        """Write raw bytes; return the offset they start at."""
        start = self._offset
        self._stream.write(data)
        self._offset += len(data)
        return start

    def _write(self, *records: McapRecord) -> tuple[int, int]:
        """Write records; return (start offset, length)."""
        builder = RecordBuilder()
        for record in records:
            record.write(builder)
        data = builder.end()
        return self._write_bytes(data), len(data)

    def add_schema(self, schema: Schema) -> None:
        """Register a schema (id chosen by the caller; a repeated id must be identical)."""
        if self._known(self.schemas, schema.id, schema):
            return
        self.schemas[schema.id] = schema
        self.stats.schema_count += 1
        self._write(schema)

    def add_channel(self, channel: Channel) -> None:
        """Register a channel (id chosen by the caller, unique in the file)."""
        if self._known(self.channels, channel.id, channel):
            return
        self.channels[channel.id] = channel
        self.stats.channel_count += 1
        self._write(channel)

    @staticmethod
    def _known(table: dict[int, Any], record_id: int, record: McapRecord) -> bool:
        if record_id in table:
            if table[record_id] != record:
                raise ValueError(f"MCAP id {record_id} is already used by a different record")
            return True
        return False

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        """A metadata record, indexed in the summary."""
        offset, length = self._write(Metadata(name=name, metadata=dict(data)))
        self._metadata_indexes.append(MetadataIndex(offset=offset, length=length, name=name))
        self.stats.metadata_count += 1

    def add_chunk(self, messages: Iterable[Message]) -> None:
        """Compress ``messages`` (of registered channels) into one chunk with its indexes.

        The records are what ``Message.write`` builds, packed here with one ``struct`` call
        each and joined once (a ``RecordBuilder`` copies every payload twice more).
        """
        pieces: list[bytes] = []
        indexes: dict[int, MessageIndex] = {}
        times = []
        offset = 0
        for message in messages:
            entry = indexes.setdefault(message.channel_id, MessageIndex(message.channel_id, []))
            entry.records.append((message.log_time, offset))
            times.append(message.log_time)
            size = len(message.data)
            pieces += (_MESSAGE_HEAD.pack(Opcode.MESSAGE, _MESSAGE_FIELDS + size,
                                          message.channel_id, message.sequence,
                                          message.log_time, message.publish_time),
                       message.data)
            offset += _MESSAGE_HEAD.size + size
        if not times:
            return
        self._add_joined(b"".join(pieces), indexes, times)

    def _add_joined(self, data: bytes, indexes: dict[int, MessageIndex], times: list[int]
                    ) -> None:
        """Compress a chunk's joined ``Message`` records and write it with its indexes."""
        compressed = self._compressor.compress(data)
        chunk = Chunk(compression="zstd", data=compressed, message_end_time=max(times),
                      message_start_time=min(times), uncompressed_crc=crc32(data),
                      uncompressed_size=len(data))
        start, length = self._write_chunk(chunk)
        index_start = self._offset
        offsets = {}
        for channel_id, index in indexes.items():
            offsets[channel_id] = self._write_bytes(_message_index(channel_id, index.records))
        self._chunk_indexes.append(ChunkIndex(
            chunk_length=length, chunk_start_offset=start, compression="zstd",
            compressed_size=len(compressed), message_end_time=chunk.message_end_time,
            message_index_length=self._offset - index_start, message_index_offsets=offsets,
            message_start_time=chunk.message_start_time, uncompressed_size=len(data)))
        counts = {cid: len(ix.records) for cid, ix in indexes.items()}
        self._count(counts, chunk.message_start_time, chunk.message_end_time, chunks=1)

    def add_message_pieces(self, channel_id: int,
                           messages: Sequence[tuple[int, int, Sequence[Any], int]]) -> None:
        """:meth:`add_chunk` for messages of one channel, each given as ``(log time in ns,
        sequence, pieces, length)``: its data is its byte-like pieces (bytes, uint8 arrays)
        back to back, ``length`` bytes. The pieces of all messages are joined once, into the
        chunk (the chunk is the one :meth:`add_chunk` writes for the joined messages)."""
        pieces: list[Any] = []
        entries = []
        offset = 0
        for log_time, sequence, data, size in messages:
            entries.append((log_time, offset))
            pieces.append(_MESSAGE_HEAD.pack(Opcode.MESSAGE, _MESSAGE_FIELDS + size, channel_id,
                                             sequence, log_time, log_time))
            pieces += data
            offset += _MESSAGE_HEAD.size + size
        if entries:
            times = [t for t, _ in entries]
            self._add_joined(b"".join(pieces), {channel_id: MessageIndex(channel_id, entries)},
                             times)

    def _write_chunk(self, chunk: Chunk) -> tuple[int, int]:
        """Write a ``Chunk`` record as ``Chunk.write`` lays it out, its compressed data
        straight from ``chunk`` (not copied through a builder); return (start, length)."""
        name = chunk.compression.encode()
        head = b"".join((
            _CHUNK_HEAD.pack(Opcode.CHUNK, _CHUNK_FIELDS + len(name) + len(chunk.data),
                             chunk.message_start_time, chunk.message_end_time,
                             chunk.uncompressed_size, chunk.uncompressed_crc, len(name)),
            name, struct.pack("<Q", len(chunk.data))))
        start = self._write_bytes(head)
        self._write_bytes(chunk.data)
        return start, len(head) + len(chunk.data)

    def add_record_chunk(self, channel_id: int, data: bytes, log_times_ns: np.ndarray) -> None:
        """Compress ready-made ``Message`` records of one channel, all of one size, into a chunk.

        ``data`` is the records' bytes back to back (e.g. :mod:`.preview` builds them as one
        NumPy array), ``log_times_ns`` their log times in ns; the message index is built at
        once too.
        """
        count = len(log_times_ns)
        if count == 0:
            return
        size = len(data) // count
        times = np.asarray(log_times_ns, dtype="<u8")
        compressed = self._compressor.compress(data)
        start_ns, end_ns = int(times.min()), int(times.max())
        chunk = Chunk(compression="zstd", data=compressed, message_end_time=end_ns,
                      message_start_time=start_ns, uncompressed_crc=crc32(data),
                      uncompressed_size=len(data))
        start, length = self._write_chunk(chunk)
        pairs = np.empty((count, 2), dtype="<u8")
        pairs[:, 0] = times
        pairs[:, 1] = np.arange(count, dtype=np.uint64) * size
        entries = pairs.tobytes()
        head = _INDEX_HEAD.pack(Opcode.MESSAGE_INDEX, _INDEX_FIELDS + len(entries), channel_id,
                                len(entries))
        index_start = self._write_bytes(head + entries)
        self._chunk_indexes.append(ChunkIndex(
            chunk_length=length, chunk_start_offset=start, compression="zstd",
            compressed_size=len(compressed), message_end_time=end_ns,
            message_index_length=self._offset - index_start,
            message_index_offsets={channel_id: index_start}, message_start_time=start_ns,
            uncompressed_size=len(data)))
        self._count({channel_id: count}, start_ns, end_ns, chunks=1)

    def _count(self, counts: dict[int, int], start_ns: int, end_ns: int, chunks: int) -> None:
        stats = self.stats
        total = sum(counts.values())
        if total == 0:
            return
        stats.message_start_time = (
            start_ns if stats.message_count == 0 else min(stats.message_start_time, start_ns)
        )
        stats.message_end_time = max(stats.message_end_time, end_ns)
        stats.message_count += total
        stats.chunk_count += chunks
        for channel_id, n in counts.items():
            stats.channel_message_counts[channel_id] = stats.channel_message_counts.get(
                channel_id, 0) + n

    def copy_chunks(self, source: IO[bytes], summary: Any) -> None:
        """Copy every chunk (and its message indexes) of another MCAP file verbatim.

        The source's channels must already be registered here under the same ids.
        """
        for index in sorted(summary.chunk_indexes, key=lambda ix: ix.chunk_start_offset):
            source.seek(index.chunk_start_offset)
            size = index.chunk_length + index.message_index_length
            raw = source.read(size)
            if len(raw) != size or raw[0] != Opcode.CHUNK:
                raise ValueError(f"chunk at offset {index.chunk_start_offset} is truncated")
            shift = self._offset - index.chunk_start_offset
            self._write_bytes(raw)
            self._chunk_indexes.append(dataclasses.replace(
                index, chunk_start_offset=index.chunk_start_offset + shift,
                message_index_offsets={k: v + shift for k, v in
                                       index.message_index_offsets.items()}))
        stats = summary.statistics
        self._count(dict(stats.channel_message_counts), stats.message_start_time,
                    stats.message_end_time, chunks=len(summary.chunk_indexes))

    def finish(self) -> None:
        """Data end, summary (schemas, channels, statistics, indexes, offsets), footer."""
        self._write(DataEnd(data_section_crc=0))
        summary_start = self._offset
        groups: list[tuple[Opcode, Sequence[McapRecord]]] = [
            (Opcode.SCHEMA, list(self.schemas.values())),
            (Opcode.CHANNEL, list(self.channels.values())),
            (Opcode.STATISTICS, [self.stats]),
            (Opcode.CHUNK_INDEX, self._chunk_indexes),
            (Opcode.METADATA_INDEX, self._metadata_indexes),
        ]
        builder = RecordBuilder()
        offsets = []
        for opcode, records in groups:
            group_start = builder.count
            for record in records:
                record.write(builder)
            offsets.append(SummaryOffset(group_opcode=opcode, group_start=summary_start +
                                         group_start, group_length=builder.count - group_start))
        offset_start = summary_start + builder.count
        for offset in offsets:
            offset.write(builder)
        summary = builder.end()
        crc = crc32(summary)
        crc = crc32(struct.pack("<BQQQ", Opcode.FOOTER, 20, summary_start, offset_start), crc)
        self._write_bytes(summary)
        self._write(Footer(summary_start=summary_start, summary_offset_start=offset_start,
                           summary_crc=crc))
        self._write_bytes(MAGIC)
