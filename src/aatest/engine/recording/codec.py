"""Exact, compact coding of sampled logs as protobuf ``SampleBlock`` messages (format v2).

Why codes: loggers produce integers — ADC codes, encoder counts, 0/1 pulses, sample numbers —
and a float64 of an ADC reading costs 8 bytes of mostly incompressible mantissa where its code
costs 2–3. A channel of a block is stored as integer ``codes`` (with ``quantum`` and ``offset``)
only when ``codes * quantum + offset``, computed in float64, gives back *every* value of the
block bit for bit (a −0.0 comes back as +0.0, the same number); otherwise it is stored as
float64 ``values``. The choice is made per block and per channel, so data off the grid (a
clipped sample, a float estimate, jittered time stamps) are never rounded: decoding always
returns the exact logged array, in its logged dtype.

Codes of smooth signals and counters (an encoder following a sine, sample numbers) are stored as
differences (``delta``), which the varints and zstd then shrink to a byte or less each.

Where the quantum comes from: integer and boolean arrays are their own codes; float arrays use
the ``(quantum, offset)`` the logger declared in :attr:`SampledLog.quantisation` (``time_s``
included), else quantum 1 when every value is a whole number (0/1 pulses stored as float).
"""

from __future__ import annotations

from collections.abc import Container, Iterable, Iterator, Mapping
from itertools import chain
from typing import Any

import numpy as np

from aatest.engine.logs import SampledLog
from aatest.engine.recording.proto import block_class

TIME_COLUMN = "time_s"
#: largest |code| a float64 carries exactly (2^53)
_MAX_EXACT_CODE = float(2**53)
_ALLOWED_KINDS = "fiub"


def _same_values(decoded: np.ndarray, logged: np.ndarray) -> bool:
    """Bitwise equality of two float64 arrays, except that −0.0 may come back as +0.0.

    The one value an integer code cannot carry is the sign of a zero (a rounded encoder reading
    just below 0 is −0.0); it is the same physical value, equal under ``==`` and in every
    computation the analyses make, so it does not force the block to float64.
    """
    return bool(np.array_equal(np.where(logged == 0.0, 0.0, logged).view(np.uint64),
                               decoded.view(np.uint64)))


def decode_codes(codes: np.ndarray, quantum: float, offset: float, dtype: np.dtype) -> np.ndarray:
    """Physical values of ``codes``: integer dtypes as themselves, floats ``code·quantum + offset``.

    The one formula the writer checks against and every reader must use (float64 arithmetic).
    ``quantum`` and ``offset`` are in the channel's own unit (V for an ADC, deg for an encoder).
    """
    if dtype.kind in "iub":
        return codes.astype(dtype)
    values = codes.astype(np.float64)
    values *= quantum  # in place: the same float64 operations, without temporaries
    values += offset
    return values.astype(dtype, copy=False)


def _codes(
    values: np.ndarray, quantum: tuple[float, float] | None
) -> tuple[np.ndarray, float, float] | None:
    """(codes, quantum, offset) reproducing ``values`` exactly, or None if there are none."""
    if values.dtype.kind in "iub":
        return values.astype(np.int64), 1.0, 0.0
    exact = values.astype(np.float64)
    step, offset = quantum if quantum is not None else (1.0, 0.0)
    if not np.isfinite(step) or step <= 0.0 or not np.isfinite(offset):
        return None
    with np.errstate(invalid="ignore", over="ignore"):
        scaled = np.round((exact - offset) / step)
    if not bool(np.all(np.abs(scaled) < _MAX_EXACT_CODE)):  # also False for NaN/inf
        return None
    codes = scaled.astype(np.int64)
    if not _same_values(codes.astype(np.float64) * step + offset, exact):
        return None
    return codes, step, offset


def _fill_channel(
    message: Any, name: str, unit: str, values: np.ndarray, quantum: tuple[float, float] | None
) -> None:
    """Fill one ``Channel`` message with codes when exact, else float64 values."""
    message.name, message.unit, message.dtype = name, unit, values.dtype.str
    coded = _codes(values, quantum)
    if coded is None:
        message.values.extend(values.astype(np.float64).tolist())
        return
    codes, step, offset = coded
    steps = np.diff(codes, prepend=np.int64(0))
    message.delta = bool(np.abs(steps).sum() < np.abs(codes).sum())  # smooth signals, counters
    message.codes.extend((steps if message.delta else codes).tolist())
    message.quantum, message.offset = step, offset


def check_dtypes(log: SampledLog) -> None:
    """Refuse channels a block cannot carry (complex, strings, objects)."""
    for name, values in log.channels.items():
        if values.dtype.kind not in _ALLOWED_KINDS:
            raise TypeError(f"channel {name!r} has unsupported dtype {values.dtype}")
    if TIME_COLUMN in log.channels:
        raise ValueError(f"{log.source} log has a channel named {TIME_COLUMN!r}")


def encode_blocks(
    log: SampledLog, header: Mapping[str, object], block_samples: int, log_times_ns: list[int]
) -> Iterator[bytes]:
    """Serialised ``SampleBlock`` messages of a log, ``block_samples`` samples each.

    ``header`` holds the block fields common to the log (``step_id``, ``step_index``, ``source``,
    ``sample_rate_hz``, ``step_record_sha256``); ``log_times_ns`` the MCAP log time of every
    block's first sample, in integer ns.
    """
    check_dtypes(log)
    block_type = block_class()
    declared = dict(log.quantisation)
    for sequence, log_time_ns in enumerate(log_times_ns):
        part = slice(sequence * block_samples, (sequence + 1) * block_samples)
        block = block_type(sequence=sequence, first_sample=part.start, log_time_ns=log_time_ns,
                           **header)
        _fill_channel(block.time, TIME_COLUMN, "s", log.time_s[part],
                      declared.get(TIME_COLUMN))
        for name, values in log.channels.items():
            _fill_channel(block.channels.add(), name, str(log.units.get(name, "")),
                          values[part], declared.get(name))
        yield block.SerializeToString()


def channel_values(message: Any) -> tuple[np.ndarray, tuple[float, float] | None]:
    """One ``Channel`` message → (values in the logged dtype, (quantum, offset) or None).

    Values, quantum and offset are in the channel's own unit (e.g. V, deg, s).
    """
    dtype = np.dtype(message.dtype)
    if dtype.kind not in _ALLOWED_KINDS or dtype.byteorder == ">":
        raise ValueError(f"channel {message.name!r} has unsupported dtype {dtype}")
    codes = message.codes
    if len(codes):
        if len(message.values):
            raise ValueError(f"channel {message.name!r} has both codes and values")
        quantum = (float(message.quantum), float(message.offset))
        integers = np.array(codes, dtype=np.int64)
        if message.delta:
            np.cumsum(integers, out=integers)
        return decode_codes(integers, *quantum, dtype), quantum
    return np.array(message.values, dtype=np.float64).astype(dtype), None


def _allocated(first: Any, samples: int, keep: Container[str] | None
               ) -> dict[str, np.ndarray]:
    """One empty array per channel (``time_s`` first), ``samples`` long, in its logged dtype.

    Laid out from the ``first`` block read (every block must carry the same channels) and
    filled block by block in place: no per-block arrays to concatenate afterwards.
    """
    columns: dict[str, np.ndarray] = {}
    for message in (first.time, *first.channels):
        if keep is not None and message.name != TIME_COLUMN and message.name not in keep:
            continue
        dtype = np.dtype(message.dtype)
        if dtype.kind not in _ALLOWED_KINDS or dtype.byteorder == ">":
            raise ValueError(f"channel {message.name!r} has unsupported dtype {dtype}")
        columns[message.name] = np.empty(samples, dtype=dtype)
    return columns


def _place(block: Any, columns: dict[str, np.ndarray], samples: int, origin: int = 0) -> int:
    """Decode one block into ``columns`` at its ``first_sample`` (less ``origin``, the first
    sample ``columns`` hold); return its sample count. ``samples``: the log's whole length."""
    size = len(block.time.codes) or len(block.time.values)
    start = int(block.first_sample)
    if start + size > samples:
        raise ValueError(f"has more samples than the {samples} its step record says")
    for message in (block.time, *block.channels):
        if message.name not in columns:
            continue
        values, _ = channel_values(message)
        if values.size != size:
            raise ValueError(f"channel {message.name!r} has {values.size} samples in "
                             f"block {block.sequence}, time has {size}")
        if values.dtype != columns[message.name].dtype:
            raise ValueError(f"channel {message.name!r} changes dtype between blocks")
        columns[message.name][start - origin:start - origin + size] = values
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

    ``blocks`` may be any iterable (a generator reading the file): each block is decoded into
    preallocated columns at its ``first_sample`` and can be dropped at once, so memory holds the
    decoded columns and one block, never every block of an hours-long record. Order and
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
    for block in chain((first,), stream):
        if [c.name for c in block.channels] != names:
            raise ValueError(f"block {block.sequence} does not continue the log")
        if block.sequence in placed:
            raise ValueError(f"block sequence number {block.sequence} is repeated")
        placed[int(block.sequence)] = (int(block.first_sample), _place(block, columns, samples))
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
            size = len(ready.time.codes) or len(ready.time.values)
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
