"""Streaming a long record into its step file chunk by chunk, with memory bounded by one chunk.

Why a spool: a step file is atomic (it exists complete or not at all, docs/interfaces.md §2) and
every block of it carries the SHA-256 of the step's metadata record, which names the sample
counts and log times of *both* loggers — known only when the record has ended and the table
log has been collected. So the DAQ chunks are encoded as they arrive into ``SampleBlock``
messages (:data:`~aatest.recording.format.BLOCK_SAMPLES` samples each, the same blocks a
one-shot write makes) and written, compressed, to a spool file ``<step file>.partial``: a
complete MCAP file of its own (run metadata, the ``/daq`` blocks; no step record), so data
recorded before a fault is on disk, readable by any MCAP reader, and never silently dropped.
When the record completes, :func:`write_streamed_step` writes the final step file from the
spool one block at a time (setting the digest in each block), exactly as
:func:`~aatest.recording.writer.write_step_file` writes the same log at once, and the
spool is deleted. A fault leaves the spool in place; the message names it, ``--resume``
records the step anew (steps stay atomic) and keeps the old spool under a numbered name.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

import numpy as np
from mcap.records import Message
from mcap.stream_reader import StreamReader

from aatest.engine.errors import StorageFault
from aatest.engine.logs import DAQ, SampledLog
from aatest.recording import codec, extremes, proto
from aatest.recording import format as fmt
from aatest.recording.channels import CHUNK_BYTES, register_channels
from aatest.recording.mcap_io import ChunkedWriter
from aatest.recording.preview import Layout, PreviewStream, records_per_chunk

#: suffix of the spool of a step being streamed
PARTIAL_SUFFIX = ".partial"
#: suffix of the side file holding the streamed DAQ's preview records
PREVIEW_SUFFIX = ".preview"


def spool_path(step_file: Path) -> Path:
    """A free spool name beside ``step_file``: ``<file>.partial``, else ``<file>.partial.N``.

    An older spool (of an attempt that faulted) is never overwritten: it holds recorded data.
    """
    candidate = step_file.with_name(step_file.name + PARTIAL_SUFFIX)
    attempt = 1
    while candidate.exists():
        attempt += 1
        candidate = step_file.with_name(f"{step_file.name}{PARTIAL_SUFFIX}.{attempt}")
    return candidate


class DaqSpool:
    """Encodes DAQ chunks into ``SampleBlock`` messages and writes them to the spool file.

    Parameters
    ----------
    path
        The spool file (created; see :func:`spool_path`).
    run_meta
        Run metadata stored in the spool (so the spool alone says what it is).
    step_id, index
        The step and its 1-based plan position (every block carries them).
    origin_ns
        The step's origin on the run time line (:func:`format.step_origin_ns`), ns.
    new_writer
        Makes the MCAP writer (the recorder's header profile).
    """

    def __init__(self, path: Path, run_meta: dict[str, Any], step_id: str, index: int,
                 origin_ns: int, new_writer: Any) -> None:
        self.path = path
        self._header = {"step_id": step_id, "step_index": index, "source": DAQ}
        self._origin_ns = origin_ns
        self._carry: SampledLog | None = None
        self.samples = 0
        self.blocks = 0
        self.first_log_ns: int | None = None
        self.last_log_ns: int | None = None
        self.sample_rate_hz: float | None = None
        self.quantisation: dict[str, tuple[float, float]] = {}
        self.extremes: dict[str, extremes.Extremes] = {}
        self._pending: list[Message] = []
        self._pending_bytes = 0
        self._closed = False
        self.preview_path = path.with_name(path.name + PREVIEW_SUFFIX)
        self._preview = PreviewStream(index, origin_ns + fmt.STEP_MARGIN_S * 1_000_000_000,
                                      origin_ns, self._spool_preview)
        try:
            self._preview_stream: IO[bytes] = open(self.preview_path, "wb")  # noqa: SIM115
            self._stream: IO[bytes] = open(path, "wb")  # noqa: SIM115 - closed in close()
            self._writer: ChunkedWriter = new_writer(self._stream)
            self._writer.add_metadata(fmt.RUN_RECORD, fmt.json_values(run_meta))
            register_channels(self._writer)
        except OSError as exc:
            raise _storage(path, exc) from exc

    @property
    def duration_s(self) -> float:
        """Lab seconds of DAQ samples received so far (at the nominal rate)."""
        return self.samples / self.sample_rate_hz if self.sample_rate_hz else 0.0

    def add(self, chunk: SampledLog) -> None:
        """Take the next chunk of the DAQ log; write every whole block it completes."""
        if chunk.source != DAQ:
            raise ValueError(f"expected a {DAQ} chunk, got {chunk.source!r}")
        if len(chunk) == 0:
            return
        codec.check_dtypes(chunk)
        if self.sample_rate_hz is None:
            self.sample_rate_hz = float(chunk.sample_rate_hz)
            self.quantisation = dict(chunk.quantisation)
        joined = chunk if self._carry is None else _concatenate(self._carry, chunk)
        whole = len(joined) // fmt.BLOCK_SAMPLES * fmt.BLOCK_SAMPLES
        if whole:
            self._encode(_slice(joined, 0, whole))
        self._carry = _slice(joined, whole, len(joined)) if whole < len(joined) else None

    def _encode(self, part: SampledLog) -> None:
        """Encode whole consecutive blocks (the last one may be short) and spool them."""
        times_ns = fmt.block_log_times_ns(part.time_s, self._origin_ns, fmt.BLOCK_SAMPLES)
        header = {**self._header, "sample_rate_hz": float(part.sample_rate_hz),
                  "step_record_sha256": ""}
        blocks = codec.encode_blocks(part, header, fmt.BLOCK_SAMPLES, times_ns,
                                     first_sequence=self.blocks, first_sample=self.samples)
        for sequence, (t_ns, data) in enumerate(zip(times_ns, blocks, strict=True),
                                                start=self.blocks):
            self._pending.append(Message(
                channel_id=fmt.CHANNEL_IDS[DAQ], log_time=t_ns, publish_time=t_ns,
                sequence=sequence, data=data))
            self._pending_bytes += len(self._pending[-1].data)
            if self._pending_bytes >= CHUNK_BYTES:
                self._flush()
        self._preview.add(part)
        self.extremes = extremes.merged_logs(self.extremes, extremes.of_log(part))
        self.blocks += len(times_ns)
        self.samples += len(part)
        self.first_log_ns = times_ns[0] if self.first_log_ns is None else self.first_log_ns
        self.last_log_ns = times_ns[-1]

    def _flush(self) -> None:
        """Compress the pending blocks into one chunk and push it to the disk."""
        try:
            self._writer.add_chunk(self._pending)
            self._stream.flush()
            os.fsync(self._stream.fileno())
        except OSError as exc:
            raise _storage(self.path, exc) from exc
        self._pending, self._pending_bytes = [], 0

    def close(self) -> None:
        """Write the last (short) block and the spool's summary; idempotent.

        Called on success before the step file is written, and on a fault so that the spool
        is a complete MCAP file holding every sample received.
        """
        if self._closed:
            return
        self._closed = True
        try:
            if self._carry is not None:
                self._encode(self._carry)
                self._carry = None
            self._flush()
            self._preview.finish()
            self._preview_stream.close()
            self._writer.finish()
            self._stream.flush()
            os.fsync(self._stream.fileno())
        except OSError as exc:
            raise _storage(self.path, exc) from exc
        finally:
            self._stream.close()

    def abandon(self) -> None:
        """Close after a fault, never raising (a second error must not hide the first)."""
        try:
            self.close()
        except Exception:  # noqa: BLE001 - best effort: what is already flushed stays on disk
            self._stream.close()
            self._preview_stream.close()
        self.preview_path.unlink(missing_ok=True)  # a view of the spool's samples, rebuilt anew

    def _spool_preview(self, layout: Layout, records: bytes, _times_ns: np.ndarray) -> None:
        """Preview records go to a side file (they are a view, not samples; not in the spool)."""
        try:
            self._preview_stream.write(records)
        except OSError as exc:
            raise _storage(self.preview_path, exc) from exc

    def preview_chunks(self) -> Iterator[tuple[Layout, bytes]]:
        """The DAQ preview records from the side file, about one chunk at a time."""
        layout = self._preview.layout
        if layout is None or not self.preview_path.exists():
            return
        size = layout.record_dtype().itemsize * records_per_chunk(layout)
        with open(self.preview_path, "rb") as stream:
            while data := stream.read(size):
                yield layout, data

    def remove(self) -> None:
        """Delete the spool and its preview side file (after the step file is written)."""
        self.path.unlink(missing_ok=True)
        self.preview_path.unlink(missing_ok=True)

    def daq_record(self) -> dict[str, Any]:
        """The DAQ's part of the step record (as :func:`writer.step_record` makes it)."""
        span = [self.first_log_ns, self.last_log_ns] if self.blocks else []
        return {
            "daq_topic": fmt.topic(DAQ),
            "daq_sample_rate_hz": float(self.sample_rate_hz or 0.0),
            "daq_samples": self.samples,
            "daq_log_time_ns": span,
            "daq_quantisation": {k: list(v) for k, v in self.quantisation.items()},
            "daq_extremes": self.extremes,
        }

    def blocks_with_digest(self, digest: str) -> Iterator[Message]:
        """The spooled DAQ messages in order, each block now carrying the step's digest."""
        block_type = proto.block_class()
        with open(self.path, "rb") as stream:
            # a linear pass, one chunk decompressed at a time (the indexed reader's unordered
            # iteration queues every message of the file before yielding the first)
            for message in StreamReader(stream, validate_crcs=True).records:
                if not isinstance(message, Message):
                    continue
                block = block_type.FromString(message.data)
                block.step_record_sha256 = digest
                yield Message(channel_id=message.channel_id, log_time=message.log_time,
                              publish_time=message.publish_time, sequence=message.sequence,
                              data=block.SerializeToString())


def _storage(path: Path, exc: OSError) -> StorageFault:
    return StorageFault(f"{path}: cannot write the streamed record ({exc.strerror or exc}); "
                        "what was recorded is kept — free space and continue with "
                        "`aatest run --resume --out RUN_DIR`")


def _slice(log: SampledLog, start: int, stop: int) -> SampledLog:
    """Samples ``start``…``stop − 1`` of a log (views; no copy)."""
    return SampledLog(log.source, log.sample_rate_hz, log.time_s[start:stop],
                      {k: v[start:stop] for k, v in log.channels.items()}, dict(log.units),
                      dict(log.quantisation))


def _concatenate(first: SampledLog, second: SampledLog) -> SampledLog:
    """Two consecutive parts of one log as one."""
    if list(first.channels) != list(second.channels):
        raise ValueError("a DAQ chunk changed its channels mid-record: "
                         f"{list(first.channels)} → {list(second.channels)}")
    return SampledLog(first.source, first.sample_rate_hz,
                      np.concatenate([first.time_s, second.time_s]),
                      {k: np.concatenate([v, second.channels[k]])
                       for k, v in first.channels.items()},
                      dict(first.units), dict(first.quantisation))
