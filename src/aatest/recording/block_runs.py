"""Decoding many ``SampleBlock`` messages of a log at once: each channel's run of alike blocks
in a few whole-array steps (the reader's half of :mod:`aatest.recording.codec`, format v3).

Why: a step of the stepped sine is 32 blocks of 4096 samples per logger, each of 5–10
channels, so decoding it block by block is ≈ 400 small decodes whose NumPy calls and Python
bookkeeping cost more than their arithmetic. A block's channel is checked when its block
arrives (:func:`plan_block`: the same checks and errors, in the same order, as a decode of
that block alone) and its packed bytes kept; a batch of blocks is then decoded channel by
channel (:func:`decode_batch`): consecutive blocks whose codes are stored alike (width, byte
planes, delta, quantum, offset, dtype, length) and which follow each other in the log are
joined into one array of one row per block, and un-shuffled, cumulated (row by row: each
block's running sum restarts at its first code) and scaled in one call each.

Every value is computed by the operations of the block-by-block decode, in the same order
per sample (:func:`~aatest.recording.codec.channel_values`, and its float64 shortcut): a
delta-coded float64 channel is summed in float64, exact while every running sum of its
whole-number codes stays below 2^53, which codes of ``width`` bytes over a block of fewer
than 2^(54 − 8·width) samples cannot reach; other channels are summed in int64 and converted
once. So the decoded arrays are the same, bit for bit.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np

#: code widths (bytes) of format v3 (:data:`aatest.recording.channel_codes.WIDTHS`)
WIDTHS = (1, 2, 4, 8)
_ALLOWED_KINDS = "fiub"
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
    if dtype.kind not in _ALLOWED_KINDS or dtype.byteorder == ">":
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
    return _codes(raw, 1, samples, width, bool(message.shuffled) and width > 1).reshape(-1)


@dataclass(frozen=True)
class _Kind:
    """How a block's channel stores its codes: blocks of one kind decode as one array."""

    width: int
    shuffled: bool
    delta: bool
    quantum: float
    offset: float
    dtype: str
    samples: int


@dataclass(frozen=True)
class Planned:
    """One block's packed channel, checked and waiting for its batch: its column, its first
    sample in the column, how its codes are stored and their bytes."""

    column: np.ndarray
    start: int
    kind: _Kind
    packed: bytes


def plan_block(block: Any, columns: Mapping[str, np.ndarray], size: int, start: int,
               plans: list[Planned]) -> None:
    """Check each kept channel of ``block`` (``size`` samples from ``start`` in its columns)
    and add its packed codes to ``plans``; a channel stored otherwise (float64 ``values``, v2
    varint ``codes``) is decoded and placed at once.

    Raises
    ------
    ValueError
        As :func:`~aatest.recording.codec.channel_values` would for the channel alone, or when
        a channel's sample count or dtype differs from its block's time stamps or columns.
    """
    for message in (block.time, *block.channels):
        column = columns.get(message.name)
        if column is None:
            continue
        name = message.name
        dtype = checked_dtype(name, message.dtype)
        packed = message.packed
        codes, values = message.codes, message.values
        if (len(packed) > 0) + (len(codes) > 0) + (len(values) > 0) > 1:
            raise ValueError(f"channel {name!r} has more than one of packed, codes, values")
        into = column[start:start + size]
        if not packed:
            _place_unpacked(message, dtype, into, block.sequence)
            continue
        width = int(message.width)
        if width not in WIDTHS or len(packed) % width:
            raise ValueError(f"channel {name!r}: {len(packed)} packed bytes do not "
                             f"make codes of width {width}")
        if len(packed) // width != size or into.size != size:
            raise ValueError(f"channel {name!r} has {len(packed) // width} samples in "
                             f"block {block.sequence}, time has {size}")
        if dtype != column.dtype:
            raise ValueError(f"channel {name!r} changes dtype between blocks")
        kind = _Kind(width, bool(message.shuffled) and width > 1, bool(message.delta),
                     float(message.quantum), float(message.offset), message.dtype, size)
        plans.append(Planned(column, start, kind, packed))


def _place_unpacked(message: Any, dtype: np.dtype, into: np.ndarray, sequence: int) -> None:
    """A channel of float64 ``values`` or v2 varint ``codes``, decoded and placed alone."""
    values, _ = channel_values(message)
    if values.size != into.size:
        raise ValueError(f"channel {message.name!r} has {values.size} samples in "
                         f"block {sequence}, time has {into.size}")
    if values.dtype != into.dtype:
        raise ValueError(f"channel {message.name!r} changes dtype between blocks")
    into[...] = values


def decode_batch(plans: list[Planned]) -> None:
    """Decode every planned channel into its column, a run of alike consecutive blocks of
    a column at a time (module docstring); ``plans`` is emptied."""
    by_column: dict[int, list[Planned]] = {}
    for plan in plans:
        by_column.setdefault(id(plan.column), []).append(plan)
    plans.clear()
    for planned in by_column.values():
        first = 0
        for i in range(1, len(planned) + 1):
            if i == len(planned) or not _continues(planned[i - 1], planned[i]):
                _decode_run(planned[first:i])
                first = i


def _continues(before: Planned, after: Planned) -> bool:
    """Whether ``after`` is stored like ``before`` and follows it in the column."""
    return after.kind == before.kind and after.start == before.start + before.kind.samples


def _decode_run(run: list[Planned]) -> None:
    """Decode consecutive blocks of one kind into their column at once, one row per block."""
    kind = run[0].kind
    rows, samples = len(run), kind.samples
    raw = np.frombuffer(run[0].packed if rows == 1 else b"".join(p.packed for p in run),
                        dtype=np.uint8)
    codes = _codes(raw, rows, samples, kind.width, kind.shuffled)
    start = run[0].start
    flat = run[0].column[start:start + rows * samples]
    into = flat.reshape(rows, samples)
    if (kind.dtype == _FLOAT64 and flat.dtype == np.float64
            and not (kind.delta and _sum_may_be_inexact(kind.width, samples))):
        into[...] = codes  # the int → float64 conversion astype makes
        if kind.delta:
            np.cumsum(into, axis=1, out=into)  # each row: one block's exact running sums
        flat *= kind.quantum
        flat += kind.offset
        return
    integers = np.cumsum(codes, axis=1, dtype=np.int64) if kind.delta else codes
    into[...] = decode_codes(integers, kind.quantum, kind.offset, np.dtype(kind.dtype))


def _sum_may_be_inexact(width: int, samples: int) -> bool:
    """Whether running sums of ``samples`` codes of ``width`` bytes may reach 2^53 (where
    float64 stops holding every whole number): then they are summed in int64."""
    return width == WIDTHS[-1] or samples >= 1 << (54 - 8 * width)


def _codes(raw: np.ndarray, rows: int, samples: int, width: int, shuffled: bool
           ) -> np.ndarray:
    """The packed integers of ``rows`` blocks of ``samples`` codes each, one row per block
    (byte planes put back together when ``shuffled``: a plane at a time, each a unit-stride
    read, where a transposed copy of the whole walks rows of 2–8 bytes)."""
    if shuffled:
        planes = raw.reshape(rows, width, samples)
        joined = np.empty((rows, samples, width), dtype=np.uint8)
        for byte in range(width):
            joined[:, :, byte] = planes[:, byte, :]
        raw = joined
    return raw.reshape(-1).view(f"<i{width}").reshape(rows, samples)
