"""The MCAP layout every aatest recording file shares: its schema, channels and chunk size.

Step files, the streamed DAQ spool (:mod:`.stream`) and the merged recording (:mod:`.writer`)
all register the same protobuf schema and the two stable logger channels, and cut chunks at
the same size; both modules import them from here.
"""

from __future__ import annotations

from mcap.records import Channel, Schema

from aatest.recording import format as fmt
from aatest.recording import proto
from aatest.recording.mcap_io import ChunkedWriter

#: chunk size before compression; 4 MiB keeps zstd efficient and memory bounded
CHUNK_BYTES = 4 * 1024 * 1024


def register_channels(writer: ChunkedWriter) -> None:
    """The one protobuf schema and the two stable channels (identical in every file)."""
    writer.add_schema(Schema(id=fmt.SCHEMA_ID, name=proto.BLOCK_MESSAGE, encoding=fmt.ENCODING,
                             data=proto.schema_data()))
    for source, cid in fmt.CHANNEL_IDS.items():
        writer.add_channel(Channel(id=cid, topic=fmt.topic(source), message_encoding=fmt.ENCODING,
                                   schema_id=fmt.SCHEMA_ID, metadata={"source": source}))
