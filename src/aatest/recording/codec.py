"""Exact, compact coding of sampled logs as protobuf ``SampleBlock`` messages (format v3).

Why codes: loggers produce integers — ADC codes, encoder counts, 0/1 pulses, sample numbers —
and a float64 of an ADC reading costs 8 bytes of mostly incompressible mantissa where its code
costs 2–3. A channel of a block is stored as integer ``codes`` (with ``quantum`` and ``offset``)
only when ``codes * quantum + offset``, computed in float64, gives back *every* value of the
block bit for bit (a −0.0 comes back as +0.0, the same number); otherwise it is stored as
float64 ``values``. The choice is made per block and per channel, so data off the grid (a
clipped sample, a float estimate, jittered time stamps) are never rounded: decoding always
returns the exact logged array, in its logged dtype.

Codes of smooth signals and counters (an encoder following a sine, sample numbers) are stored as
differences (``delta``), which zstd then shrinks to a byte or less each.

How codes are stored (v3): as ``packed`` little-endian integers of the narrowest ``width``
(1, 2, 4 or 8 bytes) that holds every code of the block, wider ones as byte planes
(``shuffled``: zstd compresses the planes of high bytes to almost nothing). Why not v2's
protobuf varints (``codes``, still read): parsing and converting varints cost ≈ 15 ns per
sample, ≈ 30 ms per step of the stepped sine and most of reading a recording; fixed-width
integers are read with :func:`numpy.frombuffer` at a few ns, and zstd compresses them as well
(measured on the stepped sine: 30 → 13 ms to decode a step, 42 → 14 ms to encode it, recording
185 → 166 MB).

Where the quantum comes from: integer and boolean arrays are their own codes; float arrays use
the ``(quantum, offset)`` the logger declared in :attr:`SampledLog.quantisation` (``time_s``
included), else quantum 1 when every value is a whole number (0/1 pulses stored as float).

The encoder's half (codes, delta choice, widths, byte planes) is
:mod:`aatest.recording.channel_codes`; the decoder's (a log's blocks decoded a channel and a
batch of blocks at a time, bit for bit as block by block) :mod:`aatest.recording.block_runs`.
"""

from __future__ import annotations

from collections.abc import Container, Iterable, Iterator, Mapping
from functools import cache
from itertools import chain
from typing import Any

import numpy as np

from aatest.engine.logs import SampledLog
from aatest.recording import proto
from aatest.recording.block_runs import (
    ALLOWED_KINDS,
    Plans,
    channel_values,
    checked_dtype,
    decode_batch,
    decode_codes,
    plan_block,
)
from aatest.recording.channel_codes import ChannelEncoder

TIME_COLUMN = "time_s"
#: field numbers (proto.py): Channel.values, Channel.packed, SampleBlock.time, .channels
_TIME_FIELD, _CHANNELS_FIELD = 7, 8
#: samples of the blocks whose codes are decoded together (a step of the stepped sine, 2^17
#: samples of 32 blocks, in one batch; an hours-long record's 60-s blocks one or two at a time)
_BATCH_SAMPLES = 1 << 18
__all__ = ["blocks_to_log", "blocks_to_pieces", "channel_values", "check_dtypes",
           "decode_codes", "encode_block_pieces", "encode_blocks", "samples_in"]


_TIME_KEY, _CHANNELS_KEY = proto.tag(_TIME_FIELD), proto.tag(_CHANNELS_FIELD)


def check_dtypes(log: SampledLog) -> None:
    """Refuse channels a block cannot carry (complex, strings, objects)."""
    for name, values in log.channels.items():
        if values.dtype.kind not in ALLOWED_KINDS:
            raise TypeError(f"channel {name!r} has unsupported dtype {values.dtype}")
    if TIME_COLUMN in log.channels:
        raise ValueError(f"{log.source} log has a channel named {TIME_COLUMN!r}")


@cache
def _block_field_numbers() -> dict[str, int]:
    """``SampleBlock`` field name → number (read from the descriptor once)."""
    return {f.name: f.number for f in proto.block_class().DESCRIPTOR.fields}


def _header_parts(header: Mapping[str, object]) -> tuple[dict[str, object], dict[str, object]]:
    """``header`` split into the block fields serialised before the channels and after them."""
    numbers = _block_field_numbers()
    unknown = set(header) - set(numbers)
    if unknown:
        raise ValueError(f"unknown SampleBlock fields {sorted(unknown)}")
    before = {k: v for k, v in header.items() if numbers[k] < _TIME_FIELD}
    return before, {k: v for k, v in header.items() if numbers[k] > _CHANNELS_FIELD}


def encode_blocks(
    log: SampledLog, header: Mapping[str, object], block_samples: int, log_times_ns: list[int],
    first_sequence: int = 0, first_sample: int = 0,
) -> Iterator[bytes]:
    """Serialised ``SampleBlock`` messages of a log, ``block_samples`` samples each.

    ``header`` holds the block fields common to the log (``step_id``, ``step_index``, ``source``,
    ``sample_rate_hz``, ``step_record_sha256``); ``log_times_ns`` the MCAP log time of every
    block's first sample, in integer ns (one per block: ``ceil(len(log) / block_samples)``).
    ``first_sequence`` and ``first_sample`` number the blocks when ``log`` continues a longer
    one (a streamed record's chunk, :mod:`aatest.recording.stream`); default 0.

    Each message is what the protobuf API serialises for the same ``SampleBlock``; the codes of
    all blocks are computed in whole-array steps over a few blocks at a time
    (:class:`ChannelEncoder`).
    """
    for pieces, _ in encode_block_pieces(log, header, block_samples, log_times_ns,
                                         first_sequence, first_sample):
        yield b"".join(pieces)  # the one copy of the samples into the message


def encode_block_pieces(
    log: SampledLog, header: Mapping[str, object], block_samples: int, log_times_ns: list[int],
    first_sequence: int = 0, first_sample: int = 0,
    coded: dict[str, list[bool]] | None = None,
) -> Iterator[tuple[list[Any], int]]:
    """:func:`encode_blocks`, each message as consecutive byte-like pieces (bytes and uint8
    arrays) with its length in bytes: a writer joins the pieces of a whole MCAP chunk at once,
    so the samples are copied once into the chunk, not into each message first.

    ``log_times_ns`` holds each block's MCAP log time in nanoseconds (UTC), one per block.
    ``coded``: filled with each channel's (``time_s`` included) per-block verdict, True where
    the block is stored as codes (its decode then gives +0.0 for a logged −0.0, the one bit
    a code cannot carry), False where as float64 values (bit for bit); what a reader of the
    logged arrays needs to hold exactly the decoded ones (:mod:`aatest.early.handover`).
    """
    check_dtypes(log)
    blocks = -(-len(log) // block_samples)
    if len(log_times_ns) != blocks:
        raise ValueError(f"{len(log_times_ns)} block log times for {blocks} blocks of "
                         f"{block_samples} samples")
    if not blocks:
        return
    starts = np.arange(blocks, dtype=np.intp) * block_samples
    declared = dict(log.quantisation)
    time = ChannelEncoder(TIME_COLUMN, "s", log.time_s, declared.get(TIME_COLUMN), starts)
    channels = [ChannelEncoder(name, str(log.units.get(name, "")), values, declared.get(name),
                                starts) for name, values in log.channels.items()]
    if coded is not None:
        coded |= {TIME_COLUMN: time.exact_blocks,
                  **{name: c.exact_blocks for name, c in zip(log.channels, channels,
                                                             strict=True)}}
    before, after = _header_parts(header)
    block_type = proto.block_class()
    # each channel's fields block by block (a generator per channel)
    columns = [time.fields(_TIME_KEY), *(c.fields(_CHANNELS_KEY) for c in channels)]
    for sequence, log_time_ns in enumerate(log_times_ns):
        head = block_type(sequence=first_sequence + sequence,
                          first_sample=first_sample + sequence * block_samples, **before)
        parts = [head.SerializeToString()]
        length = len(parts[0])
        for column in columns:
            pieces, size = next(column)
            parts += pieces
            length += size
        parts.append(block_type(log_time_ns=log_time_ns, **after).SerializeToString())
        yield parts, length + len(parts[-1])


def samples_in(message: Any) -> int:
    """The number of samples a ``Channel`` message holds (whichever way they are stored)."""
    if message.packed:
        return len(message.packed) // max(int(message.width), 1)
    return len(message.codes) or len(message.values)


def _allocated(first: Any, samples: int, keep: Container[str] | None
               ) -> dict[str, np.ndarray]:
    """One empty array per channel (``time_s`` first), ``samples`` long, in its logged dtype.

    Laid out from the ``first`` block read (every block must carry the same channels) and
    filled in place, a batch of blocks at a time: no per-block arrays to concatenate
    afterwards.
    """
    columns: dict[str, np.ndarray] = {}
    for message in (first.time, *first.channels):
        if keep is not None and message.name != TIME_COLUMN and message.name not in keep:
            continue
        columns[message.name] = np.empty(samples, dtype=checked_dtype(message.name,
                                                                      message.dtype))
    return columns


def _place(block: Any, columns: dict[str, np.ndarray], samples: int, origin: int = 0,
           plans: Plans | None = None) -> int:
    """Check one block and decode it into ``columns`` at its ``first_sample`` (less
    ``origin``, the first sample ``columns`` hold); return its sample count. ``samples``: the
    log's whole length. ``plans``: add its packed channels there, to be decoded with the
    blocks after it (:func:`~aatest.recording.block_runs.decode_batch`); None: decode now."""
    size = samples_in(block.time)
    start = int(block.first_sample)
    if start + size > samples:
        raise ValueError(f"has more samples than the {samples} its step record says")
    pending: Plans = {} if plans is None else plans
    plan_block(block, columns, size, start - origin, pending)
    if plans is None:
        decode_batch(pending, columns)
    return size


def _check_continuity(placed: Mapping[int, tuple[int, int]], samples: int) -> None:
    """Blocks ``sequence → (first_sample, size)`` must tile ``0 … samples`` in sequence order.

    Checked after filling, because blocks may arrive in any order (chunks in file order).
    """
    sequences = sorted(placed)
    if sequences != list(range(len(sequences))):
        raise ValueError(f"block sequence numbers {sequences} have gaps")
    position = 0
    for sequence in sequences:
        start, size = placed[sequence]
        if start != position:
            raise ValueError(f"block {sequence} does not continue the log")
        position += size
    if position != samples:
        raise ValueError(f"has {position} samples, its step record says {samples}")


def blocks_to_log(
    blocks: Iterable[Any], source: str, sample_rate_hz: float, samples: int,
    quantisation: Mapping[str, tuple[float, float]], channels: Container[str] | None = None,
) -> SampledLog:
    """Rebuild one step's :class:`SampledLog` from its decoded ``SampleBlock`` messages.

    ``blocks`` may be any iterable (a generator reading the file): each block is checked as it
    comes and can be dropped at once; its packed codes wait for the next few blocks (up to
    :data:`_BATCH_SAMPLES` samples) and are decoded with them into preallocated columns at
    their ``first_sample`` (:mod:`aatest.recording.block_runs`). So memory holds the decoded
    columns and a few blocks' codes, never every block of an hours-long record. Order and
    continuity are checked once all blocks are placed.

    ``sample_rate_hz`` is the logger's nominal rate in Hz, ``samples`` the count the step record
    gives, ``quantisation`` the declared ``(quantum, offset)`` per channel in its own unit (V, deg).
    ``channels``: decode only these (and the time stamps), e.g. the sync pulses; default all.

    Raises
    ------
    ValueError
        Blocks are missing, repeated or out of place, channels differ between blocks, or the
        sample count is not ``samples``.
    """
    stream = iter(blocks)
    first = next(stream, None)
    if first is None:
        if samples:
            raise ValueError(f"has 0 samples, its step record says {samples}")
        return SampledLog(source, sample_rate_hz, np.empty(0), {}, {}, quantisation)
    names = [c.name for c in first.channels]
    columns = _allocated(first, samples, channels)
    units = {c.name: c.unit for c in first.channels if c.name in columns}
    placed: dict[int, tuple[int, int]] = {}
    plans: Plans = {}
    batched = 0  # samples of the blocks in ``plans``
    for block in chain((first,), stream):
        if [c.name for c in block.channels] != names:
            raise ValueError(f"block {block.sequence} does not continue the log")
        if block.sequence in placed:
            raise ValueError(f"block sequence number {block.sequence} is repeated")
        size = _place(block, columns, samples, plans=plans)
        placed[int(block.sequence)] = (int(block.first_sample), size)
        batched += size
        if batched >= _BATCH_SAMPLES:
            decode_batch(plans, columns)
            batched = 0
    decode_batch(plans, columns)
    _check_continuity(placed, samples)
    return _as_log(columns, source, sample_rate_hz, units, quantisation, channels)


def _as_log(columns: dict[str, np.ndarray], source: str, sample_rate_hz: float,
            units: Mapping[str, str], quantisation: Mapping[str, tuple[float, float]],
            channels: Container[str] | None) -> SampledLog:
    """The filled columns (``time_s`` among them) as a read-only :class:`SampledLog`."""
    for values in columns.values():
        values.flags.writeable = False  # SampledLog then keeps it without copying
    time_s = columns.pop(TIME_COLUMN).astype(np.float64, copy=False)
    kept = quantisation if channels is None else {
        k: v for k, v in quantisation.items() if k == TIME_COLUMN or k in columns}
    return SampledLog(source, sample_rate_hz, time_s, columns, units, kept)


def blocks_to_pieces(
    blocks: Iterable[Any], source: str, sample_rate_hz: float, samples: int,
    quantisation: Mapping[str, tuple[float, float]], channels: Container[str] | None = None,
) -> Iterator[SampledLog]:
    """One step's log as consecutive pieces, one per block, in sample order.

    Why: a reduction over an hours-long record (block means) needs one block at a time, not
    the record (115 MB per channel for 2 h at 2 kHz). Arguments as for :func:`blocks_to_log`.
    A block that arrives before its predecessors is held until their turn (a step's blocks are
    written in order, so in practice none is held). The same checks as :func:`blocks_to_log`
    are made as the blocks come: a ``ValueError`` may come after pieces were yielded.
    """
    pending: dict[int, Any] = {}
    names: list[str] | None = None
    position = sequence = 0
    for block in blocks:
        if names is None:
            names = [c.name for c in block.channels]
        if [c.name for c in block.channels] != names:
            raise ValueError(f"block {block.sequence} does not continue the log")
        if block.sequence in pending or block.sequence < sequence:
            raise ValueError(f"block sequence number {block.sequence} is repeated")
        pending[int(block.sequence)] = block
        while sequence in pending:
            ready = pending.pop(sequence)
            if ready.first_sample != position:
                raise ValueError(f"block {sequence} does not continue the log")
            size = samples_in(ready.time)
            columns = _allocated(ready, size, channels)
            _place(ready, columns, samples, origin=position)
            units = {c.name: c.unit for c in ready.channels if c.name in columns}
            yield _as_log(columns, source, sample_rate_hz, units, quantisation, channels)
            position += size
            sequence += 1
    if pending:
        raise ValueError(f"block sequence numbers {sorted(pending)} have gaps")
    if position != samples:
        raise ValueError(f"has {position} samples, its step record says {samples}")
