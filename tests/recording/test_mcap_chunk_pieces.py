"""A chunk handed over as message pieces is the chunk of the joined messages, byte for byte.

The step writer gives :meth:`ChunkedWriter.add_message_pieces` each block as its pieces
(bytes, byte-plane views) so the samples are copied once, into the chunk; the file must be
the one :meth:`ChunkedWriter.add_chunk` writes for the same messages joined, and a standard
MCAP reader must give every message back.
"""

from __future__ import annotations

import io
import zlib
from typing import Any

import numpy as np
import zstandard
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.reader import make_reader
from mcap.records import Channel, Chunk, Message, MessageIndex, Schema
from mcap.stream_reader import StreamReader

from aatest.recording.mcap_io import ChunkedWriter


def _file(pieces_api: bool, messages: list[tuple[int, int, list[Any]]]) -> bytes:
    stream = io.BytesIO()
    writer = ChunkedWriter(stream, profile="test", library="test")
    writer.add_schema(Schema(id=1, name="blob", encoding="", data=b""))
    writer.add_channel(Channel(id=7, topic="/blocks", message_encoding="", schema_id=1,
                               metadata={}))
    if pieces_api:
        writer.add_message_pieces(7, [(t, seq, parts, sum(len(memoryview(p).cast("B"))
                                                            for p in parts))
                                      for t, seq, parts in messages])
    else:
        writer.add_chunk([Message(channel_id=7, sequence=seq, log_time=t, publish_time=t,
                                  data=b"".join(parts)) for t, seq, parts in messages])
    writer.finish()
    return stream.getvalue()


def test_message_pieces_make_the_chunk_of_the_joined_messages() -> None:
    rng = np.random.default_rng(2)
    planes = rng.integers(0, 256, 3 * 64, dtype=np.uint8)
    messages: list[tuple[int, int, list[Any]]] = [
        (10**9 + 5 * k, k, [b"head%d" % k, memoryview(planes.tobytes())[64 * k:64 * (k + 1)],
                            planes[k:k + 9], b"tail"])
        for k in range(3)]
    messages.append((10**9 + 99, 3, [b""]))  # an empty message
    joined = _file(False, messages)
    assert _file(True, messages) == joined
    read = [(m.log_time, m.sequence, m.data) for _, _, m in
            make_reader(io.BytesIO(joined)).iter_messages()]
    assert read == [(t, seq, b"".join(bytes(memoryview(p).cast("B")) for p in parts))
                    for t, seq, parts in messages]


def test_chunk_crc_and_message_index_are_the_mcap_records() -> None:
    """The chunk's CRC is zlib's CRC-32 of its messages (computed by zlib-ng), and the message
    index packed by hand is the record ``MessageIndex.write`` builds."""
    rng = np.random.default_rng(3)
    messages: list[tuple[int, int, list[Any]]] = [
        (10**9 + 7 * k, k, [rng.integers(0, 256, 1000 + k, dtype=np.uint8).tobytes()])
        for k in range(5)]
    data = _file(True, messages)
    records = list(StreamReader(io.BytesIO(data), emit_chunks=True,
                                validate_crcs=True).records)
    chunk = next(r for r in records if isinstance(r, Chunk))
    messages_bytes = zstandard.ZstdDecompressor().decompress(chunk.data)
    assert chunk.uncompressed_crc == zlib.crc32(messages_bytes)
    index = next(r for r in records if isinstance(r, MessageIndex))
    builder = RecordBuilder()
    MessageIndex(channel_id=7, records=index.records).write(builder)
    start = data.index(builder.end())  # the record mcap builds is in the file, verbatim
    assert data[start] == Opcode.MESSAGE_INDEX
    offsets, offset = [], 0
    for _, _, parts in messages:
        offsets.append(offset)
        offset += 31 + len(parts[0])  # a Message record's opcode, length and fields
    assert index.records == [(t, o) for (t, _, _), o in zip(messages, offsets, strict=True)]
