"""A chunk handed over as message pieces is the chunk of the joined messages, byte for byte.

The step writer gives :meth:`ChunkedWriter.add_message_pieces` each block as its pieces
(bytes, byte-plane views) so the samples are copied once, into the chunk; the file must be
the one :meth:`ChunkedWriter.add_chunk` writes for the same messages joined, and a standard
MCAP reader must give every message back.
"""

from __future__ import annotations

import io
from typing import Any

import numpy as np
from mcap.reader import make_reader
from mcap.records import Channel, Message, Schema

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
