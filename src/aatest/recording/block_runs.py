"""Decoding many ``SampleBlock`` messages of a log at once: each channel's run of alike blocks
in a few whole-array steps (the reader's half of :mod:`aatest.recording.codec`, format v3).

Why: a step of the stepped sine is 32 blocks of 4096 samples per logger, each of 5–10
channels, so decoding it block by block is ≈ 400 small decodes whose NumPy calls and Python
bookkeeping cost more than their arithmetic. A block's channel is checked when its block
arrives (:func:`plan_block`: the same checks and errors, in the same order, as a decode of
that block alone) and its packed bytes kept; a batch of blocks is then decoded channel by
channel (:func:`decode_batch`): the blocks of a float64 channel stored alike but for their
code widths (delta, quantum, offset, dtype, length), which tile a part of the log, are
decoded as one grid of one row per block: each width's codes joined, un-shuffled and
converted into their rows at once, then every row cumulated (each block's running sum
restarts at its first code) and scaled in one call each. Other channels (integers, 8-byte
deltas) are decoded a run of alike consecutive blocks at a time.

Every value is computed by the operations of the block-by-block decode, in the same order
per sample (:func:`~aatest.recording.codec.channel_values`, and its float64 shortcut): a
delta-coded float64 channel is summed in float64, exact while every running sum of its
whole-number codes stays below 2^53, which codes of ``width`` bytes over a block of fewer
than 2^(54 − 8·width) samples cannot reach; other channels are summed in int64 and converted
once. So the decoded arrays are the same, bit for bit.
"""

from __future__ import annotations

import math
import struct
import threading
from collections.abc import Iterator, Mapping
from functools import lru_cache
from typing import Any, NamedTuple

import numpy as np

from aatest.recording.channel_codes import WIDTHS

#: the dtype kinds a block's channel may have (floats, signed and unsigned integers, bools)
ALLOWED_KINDS = "fiub"
#: the dtype string of a float64 channel as the writer stores it
_FLOAT64 = np.dtype(np.float64).str


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


@lru_cache(maxsize=256)
def checked_dtype(name: str, dtype_str: str) -> np.dtype:
    """The dtype a ``Channel`` names, refused when a block cannot carry it (memoised: a run
    has a few)."""
    dtype = np.dtype(dtype_str)
    if dtype.kind not in ALLOWED_KINDS or dtype.byteorder == ">":
        raise ValueError(f"channel {name!r} has unsupported dtype {dtype}")
    return dtype


def channel_values(message: Any) -> tuple[np.ndarray, tuple[float, float] | None]:
    """One ``Channel`` message → (values in the logged dtype, (quantum, offset) or None).

    Values, quantum and offset are in the channel's own unit (e.g. V, deg, s). Codes may be
    ``packed`` (v3) or varint ``codes`` (v2); a message holds one of the three kinds.
    """
    dtype = checked_dtype(message.name, message.dtype)
    packed, codes, values = message.packed, message.codes, message.values
    if (len(packed) > 0) + (len(codes) > 0) + (len(values) > 0) > 1:
        raise ValueError(f"channel {message.name!r} has more than one of packed, codes, values")
    if not packed and not len(codes):
        return np.array(values, dtype=np.float64).astype(dtype), None
    quantum = (float(message.quantum), float(message.offset))
    integers = unpacked(message) if packed else np.array(codes, dtype=np.int64)
    if message.delta:
        integers = np.cumsum(integers, dtype=np.int64)
    return decode_codes(integers, *quantum, dtype), quantum


def unpacked(message: Any) -> np.ndarray:
    """The integers of a v3 ``packed`` field, in their stored width."""
    width = int(message.width)
    packed = message.packed
    if width not in WIDTHS or len(packed) % width:
        raise ValueError(f"channel {message.name!r}: {len(packed)} packed bytes do not "
                         f"make codes of width {width}")
    raw = np.frombuffer(packed, dtype=np.uint8)
    samples = len(packed) // width
    codes = _codes(raw, 1, samples, width, bool(message.shuffled) and width > 1)
    return codes.reshape(-1).copy() if message.shuffled and width > 1 else codes.reshape(-1)


class _Kind(NamedTuple):
    """How a block's channel stores its codes: blocks of one kind decode as one array."""

    width: int
    shuffled: bool
    delta: bool
    quantum: float
    offset: float
    dtype: str
    samples: int
    #: ``quantum`` and ``offset`` as bytes: kinds compare equal only when their scaling is
    #: the same bit for bit (as floats, an offset of −0.0 equals one of +0.0)
    scale: bytes


class Planned(NamedTuple):
    """One block's packed channel, checked and waiting for its batch: its first sample in
    its column, how its codes are stored and their bytes."""

    start: int
    kind: _Kind
    packed: bytes


_SCALE = struct.Struct("<dd")
#: channel name → its planned blocks, in the order they came
Plans = dict[str, list[Planned]]


def plan_block(block: Any, columns: Mapping[str, np.ndarray], size: int, start: int,
               plans: Plans) -> None:
    """Check each kept channel of ``block`` (``size`` samples from ``start`` in its columns)
    and add its packed codes to ``plans``; a channel stored otherwise (float64 ``values``, v2
    varint ``codes``) is decoded and placed at once.

    Raises
    ------
    ValueError
        As :func:`channel_values` would for the channel alone, or when a channel's sample
        count or dtype differs from its block's time stamps or columns.
    """
    for message in (block.time, *block.channels):
        name = message.name
        column = columns.get(name)
        if column is None:
            continue
        dtype = checked_dtype(name, message.dtype)
        packed = message.packed
        if (len(packed) > 0) + (len(message.codes) > 0) + (len(message.values) > 0) > 1:
            raise ValueError(f"channel {name!r} has more than one of packed, codes, values")
        if not packed:
            _place_unpacked(message, dtype, column[start:start + size], block.sequence)
            continue
        width = message.width
        if width not in WIDTHS or len(packed) % width:
            raise ValueError(f"channel {name!r}: {len(packed)} packed bytes do not "
                             f"make codes of width {width}")
        if len(packed) // width != size or start + size > column.size:
            raise ValueError(f"channel {name!r} has {len(packed) // width} samples in "
                             f"block {block.sequence}, time has {size}")
        if dtype != column.dtype:
            raise ValueError(f"channel {name!r} changes dtype between blocks")
        quantum, offset = message.quantum, message.offset
        kind = _Kind(width, message.shuffled and width > 1, message.delta, quantum, offset,
                     message.dtype, size, _SCALE.pack(quantum, offset))
        plans.setdefault(name, []).append(Planned(start, kind, packed))


def _place_unpacked(message: Any, dtype: np.dtype, into: np.ndarray, sequence: int) -> None:
    """A channel of float64 ``values`` or v2 varint ``codes``, decoded and placed alone."""
    values, _ = channel_values(message)
    if values.size != into.size:
        raise ValueError(f"channel {message.name!r} has {values.size} samples in "
                         f"block {sequence}, time has {into.size}")
    if values.dtype != into.dtype:
        raise ValueError(f"channel {message.name!r} changes dtype between blocks")
    into[...] = values


def decode_batch(plans: Plans, columns: Mapping[str, np.ndarray]) -> None:
    """Decode every planned channel into its column (module docstring); ``plans`` is emptied.

    A channel's float64 blocks that differ only in their code width are decoded together
    (:func:`_decode_grid`); any others a run of alike consecutive blocks at a time.
    """
    for name, planned in plans.items():
        column = columns[name]
        groups: dict[tuple[Any, ...], list[Planned]] = {}
        for plan in planned:
            groups.setdefault(plan.kind[2:], []).append(plan)  # all but width and planes
        for group in groups.values():
            if not _decode_grid(group, column):
                _decode_runs(group, column)
    plans.clear()


def _decode_runs(planned: list[Planned], column: np.ndarray) -> None:
    """Decode ``planned`` a run of alike consecutive blocks at a time (:func:`_decode_run`)."""
    first = 0
    for i in range(1, len(planned) + 1):
        if i == len(planned) or not _continues(planned[i - 1], planned[i]):
            _decode_run(planned[first:i], column)
            first = i


def _decode_grid(group: list[Planned], column: np.ndarray) -> bool:
    """Decode blocks of a float64 channel stored alike but for their widths, which tile a
    part of ``column`` (in any order), at once: each width's codes converted into their rows,
    then every row cumulated (:func:`_running_sums`) and scaled together. False, with nothing
    written, for blocks that do not tile (a damaged log) or need the int64 path."""
    kind = group[0].kind
    samples = kind.samples
    if (kind.dtype != _FLOAT64 or column.dtype != np.float64 or samples == 0
            or (kind.delta and any(_sum_may_be_inexact(p.kind.width, samples) for p in group))):
        return False
    base = min(p.start for p in group)
    rows = [(p.start - base) // samples for p in group]
    if (any((p.start - base) % samples for p in group)
            or sorted(rows) != list(range(len(group)))):
        return False
    flat = column[base:base + len(group) * samples]
    grid = flat.reshape(len(group), samples)
    if kind.delta and len(group) > 1:
        _running_sums(group, rows, grid)
    else:
        for codes, where in _by_storage(group, rows):
            grid[where] = codes  # the int → float64 conversion astype makes
        if kind.delta:
            np.cumsum(grid, axis=1, out=grid)
    flat *= kind.quantum
    if not _adds_nothing(kind.quantum, kind.offset):
        flat += kind.offset
    return True


def _by_storage(group: list[Planned], rows: list[int]
                ) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """The codes of ``group``'s blocks by (width, byte planes), one row per block, and the
    rows of the grid (:func:`_decode_grid`) they go to. A generator: each width's codes are
    a temporary (:func:`_scratch`), to be used before the next is asked for."""
    parts: dict[tuple[int, bool], list[tuple[int, bytes]]] = {}
    for plan, row in zip(group, rows, strict=True):
        parts.setdefault((plan.kind.width, plan.kind.shuffled), []).append((row, plan.packed))
    samples = group[0].kind.samples
    for (width, shuffled), blocks in parts.items():
        payload = blocks[0][1] if len(blocks) == 1 else b"".join(p for _, p in blocks)
        codes = _codes(np.frombuffer(payload, dtype=np.uint8), len(blocks), samples, width,
                       shuffled)
        yield codes, np.array([row for row, _ in blocks], dtype=np.intp)


def _continues(before: Planned, after: Planned) -> bool:
    """Whether ``after`` is stored like ``before`` and follows it in the column."""
    return after.kind == before.kind and after.start == before.start + before.kind.samples


def _decode_run(run: list[Planned], column: np.ndarray) -> None:
    """Decode consecutive blocks of one kind into their column at once, one row per block,
    by :func:`channel_values`' int64 path (the kinds :func:`_decode_grid` leaves)."""
    kind = run[0].kind
    rows, samples = len(run), kind.samples
    raw = np.frombuffer(run[0].packed if rows == 1 else b"".join(p.packed for p in run),
                        dtype=np.uint8)
    codes = _codes(raw, rows, samples, kind.width, kind.shuffled)
    start = run[0].start
    into = column[start:start + rows * samples].reshape(rows, samples)
    integers = np.cumsum(codes, axis=1, dtype=np.int64) if kind.delta else codes
    into[...] = decode_codes(integers, kind.quantum, kind.offset, np.dtype(kind.dtype))


def _running_sums(group: list[Planned], rows: list[int], grid: np.ndarray) -> None:
    """Each block's running sums of its codes in float64, into its row of ``grid``: two rows
    at a time, as the real and imaginary parts of one complex128 running sum.

    Why: a running sum waits for the sum before it (≈ 3 ns a sample however it is written
    in NumPy); a complex sum makes two independent float64 additions in that time, so two
    blocks are summed for the price of one. The additions are those of a float64 running
    sum of each row (a complex addition adds the real and the imaginary parts apart), exact
    for the whole numbers summed here (:func:`_sum_may_be_inexact`).
    """
    count, samples = grid.shape
    pairs = (count + 1) // 2
    lanes = _scratch("lanes", (pairs, samples, 2), np.float64)  # row r: lanes[r // 2, :, r % 2]
    by_row = lanes.transpose(0, 2, 1)  # (pairs, 2, samples): the rows, as a view
    if count % 2:
        by_row[-1, 1] = 0.0  # the odd row's partner: zeros
    for codes, where in _by_storage(group, rows):
        by_row[where // 2, where % 2] = codes  # int → float64, as astype converts
    sums = lanes.view(np.complex128)[:, :, 0]
    np.cumsum(sums, axis=1, out=sums)
    even = count - count % 2
    grid[:even].reshape(even // 2, 2, samples)[...] = by_row[:even // 2]
    if count % 2:
        grid[-1] = by_row[-1, 0]


#: bytes up to which a temporary array is kept for the next decode (:func:`_scratch`)
_SCRATCH_BYTES = 1 << 23
_local = threading.local()


def _scratch(name: str, shape: tuple[int, ...], dtype: type[np.generic]) -> np.ndarray:
    """A temporary array for this thread, uninitialised, kept for the next call of ``name``
    when at most :data:`_SCRATCH_BYTES` (a few MB for good); larger ones are fresh.

    Why: a step's decode needs a temporary of ≈ 1 MB per channel; allocated anew each time,
    the C library hands such blocks back to the kernel and takes them again, and the page
    faults cost ≈ a third of the decode's CPU time. The caller must not keep it.
    """
    size = int(np.prod(shape)) * np.dtype(dtype).itemsize
    if size > _SCRATCH_BYTES:
        return np.empty(shape, dtype=dtype)
    kept: dict[str, np.ndarray] = _local.__dict__.setdefault("scratch", {})
    buffer = kept.get(name)
    if buffer is None or buffer.size < size:
        buffer = kept[name] = np.empty(max(size, 1 << 20), dtype=np.uint8)
    return buffer[:size].view(dtype).reshape(shape)


def _adds_nothing(quantum: float, offset: float) -> bool:
    """Whether adding ``offset`` to every ``code·quantum`` leaves it as it is, bit for bit:
    for an offset of +0.0 and a finite quantum > 0, no product is −0.0 (a code is a whole
    number: 0 gives +0.0, any other at least ``quantum`` in magnitude), and ``x + 0.0`` is
    ``x`` for any other ``x`` (±inf included)."""
    return offset == 0.0 and math.copysign(1.0, offset) > 0 and 0.0 < quantum < math.inf


def _sum_may_be_inexact(width: int, samples: int) -> bool:
    """Whether running sums of ``samples`` codes of ``width`` bytes may reach 2^53 (where
    float64 stops holding every whole number): then they are summed in int64."""
    return width == WIDTHS[-1] or samples >= 1 << (54 - 8 * width)


def _codes(raw: np.ndarray, rows: int, samples: int, width: int, shuffled: bool
           ) -> np.ndarray:
    """The packed integers of ``rows`` blocks of ``samples`` codes each, one row per block
    (byte planes put back together when ``shuffled``: a plane at a time, each a unit-stride
    read, where a transposed copy of the whole walks rows of 2–8 bytes). Put together, they
    are a temporary (:func:`_scratch`): used before the next call, never kept."""
    if shuffled:
        planes = raw.reshape(rows, width, samples)
        joined = _scratch("planes", (rows, samples, width), np.uint8)
        for byte in range(width):
            joined[:, :, byte] = planes[:, byte, :]
        raw = joined
    return raw.reshape(-1).view(f"<i{width}").reshape(rows, samples)
