"""A sampled channel as the integer codes of format v3, block by block (the writer's half of
:mod:`aatest.recording.codec`).

The codes are *defined* by ``round((x − offset) / quantum)`` (:func:`coded_by_division`),
kept for a block only where ``code·quantum + offset`` gives back every value bit for bit. A
channel whose values are small against ``2^47`` quanta (every channel of a rig: ADC codes,
encoder counts, time steps) gets the same codes and verdicts from a multiplication by
``1/quantum`` (:func:`coded_by_reciprocal`, a third of the division's cost; the bound is
derived in :func:`reciprocal_is_exact`), in int32 when they fit. A channel is coded in
passes of a few blocks (:data:`_PASS_SAMPLES`, so a pass's arrays stay in cache), each pass
taking its own route: the bound holds sample by sample, so it may be tested on any part of
a channel. A pass's byte planes are cut once, from the narrow integers, block after block,
and each block's message is handed over as pieces to be joined once, into the MCAP chunk:
on the stepped sine, writing a step file took ≈ 55 → 31 ms of CPU, then ≈ 30 → 26 ms
(bench/step_writer.py, same bytes), then ≈ 24 → 22.5 ms with the per-block lookups made once
per channel, the passes planned once per log and passes of equal values coded from one value
(:meth:`ChannelEncoder._add_constant`).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Iterator
from dataclasses import dataclass
from functools import cache, lru_cache
from itertools import compress, pairwise
from operator import sub
from typing import Any

import numpy as np

from aatest.recording import proto

#: field numbers (proto.py): Channel.values, Channel.packed
_VALUES_FIELD, _PACKED_FIELD = 4, 9
#: largest |code| a float64 carries exactly (2^53)
_MAX_EXACT_CODE = float(2**53)


@dataclass(frozen=True)
class _Coded:
    """One channel of a whole log as codes, and which of its blocks they reproduce exactly."""

    codes: np.ndarray  # int64 (int32 if all fit), one per sample (meaningless inside blocks
    #                    that are not exact)
    exact: np.ndarray  # bool, one per block
    quantum: float
    offset: float
    #: above every |code| (also in blocks that are not exact); inf when unknown
    limit: float = float("inf")


#: ``(max|x| + 2·|offset|) / quantum`` up to which a channel's codes may be found by
#: multiplying with ``1 / quantum`` instead of dividing (:func:`coded_by_reciprocal`)
_RECIPROCAL_SAFE_CODES = float(2**47)
#: ... up to which every code, and every difference of two, fits an int32: half the memory
#: traffic for the delta choice and the byte planes (codes of ±2^29 differ by < 2^31)
_INT32_SAFE_CODES = float(2**29)


def coded(values: np.ndarray, quantum: tuple[float, float] | None, starts: np.ndarray,
          extremes: tuple[float, float] | None = None) -> _Coded:
    """Integer codes of a whole channel, with each block's verdict: do its codes give back every
    value bit for bit? (The per-block choice of :func:`encode_blocks`, made for many at once.)

    Codes come from :func:`coded_by_reciprocal` where the channel's magnitude makes it give
    exactly the codes and verdicts of :func:`coded_by_division` (the definition), else from
    the latter.

    ``step``/``quantum`` and ``offset`` are in the channel's own unit (V for an ADC, deg for an
    encoder); codes and ``limit`` are dimensionless. ``extremes``: the least and the largest
    value of a float64 ``values``, if the caller has them (:func:`_extremes`).
    """
    if values.dtype.kind in "iub":
        return _Coded(values.astype(np.int64), np.ones(starts.size, dtype=bool), 1.0, 0.0)
    exact = values.astype(np.float64, copy=False)
    step, offset = quantum if quantum is not None else (1.0, 0.0)
    if not math.isfinite(step) or step <= 0.0 or not math.isfinite(offset):
        return _Coded(np.zeros(values.size, np.int64), np.zeros(starts.size, bool), step, offset)
    ratio = _code_ratio(exact, step, offset, extremes)
    if _admits_reciprocal(ratio):
        integers = np.int32 if ratio <= _INT32_SAFE_CODES else np.int64
        return coded_by_reciprocal(exact, step, offset, starts, integers, ratio + 1.0)
    return coded_by_division(exact, step, offset, starts)


def _extremes(exact: np.ndarray) -> tuple[float, float]:
    """The least and the largest value of a float64 array (NaN for both if it holds a NaN)."""
    return float(np.minimum.reduce(exact)), float(np.maximum.reduce(exact))


def _code_ratio(exact: np.ndarray, step: float, offset: float,
                extremes: tuple[float, float] | None = None) -> float:
    """``(max|x| + 2·|offset|) / step`` of a channel: above every code's magnitude (NaN or
    inf for a channel holding NaN or inf, or none at all). ``extremes``: its
    :func:`_extremes`, if known."""
    if exact.size == 0:
        return float("nan")
    low, high = extremes if extremes is not None else _extremes(exact)
    top = max(high, -low)
    # in Python floats an overflow is inf and NaN stays NaN, without NumPy's warnings
    return (top + 2.0 * abs(float(offset))) / float(step)


def reciprocal_is_exact(exact: np.ndarray, step: float, offset: float) -> bool:
    """Whether rounding ``(x − offset)·(1/step)`` gives every code :func:`coded_by_division`
    finds exact, for every value ``x`` of the channel (``step`` > 0 and ``offset`` finite).

    Why it does when ``(max|x| + 2·|offset|)/step ≤ 2^47``: if ``x = fl(fl(c·step) + offset)``
    for a code ``c``, then ``|c| + |offset|/step < 2^48`` and the float64 roundings of the
    subtraction, of ``1/step`` and of the product move the quotient from ``c`` by at most
    ``5.1·2^-53·2^48 ≈ 0.16`` (and the division's by less): both round to ``c``. A value no
    code gives back fails the check whichever code is tried. So every sample gets the same
    verdict, and every exact one the same code, by either route. NaN or ±inf in the channel
    (or a ratio beyond 2^47) keeps the division. The argument is made sample by sample, so
    it holds for any part of a channel that meets the bound (:class:`ChannelEncoder` tests
    it pass by pass).

    ``step``/``quantum`` and ``offset`` are in the channel's own unit (V for an ADC, deg for an
    encoder); codes and ``limit`` are dimensionless.
    """
    return _admits_reciprocal(_code_ratio(exact, step, offset))


def _admits_reciprocal(ratio: float) -> bool:
    """The bound of :func:`reciprocal_is_exact` on a channel's :func:`_code_ratio` (the one
    place it is tested; False for NaN and inf)."""
    return bool(ratio <= _RECIPROCAL_SAFE_CODES)


def coded_by_reciprocal(exact: np.ndarray, step: float, offset: float, starts: np.ndarray,
                         integers: type[np.signedinteger[Any]] = np.int64,
                         limit: float = float("inf")) -> _Coded:
    """:func:`coded_by_division` for a channel :func:`reciprocal_is_exact` accepts: one
    multiplication for the division (a third of its cost), and no test of which codes fit
    (all are below 2^48). ``integers``: the dtype of the codes (int32 when they fit).

    ``step``/``quantum`` and ``offset`` are in the channel's own unit (V for an ADC, deg for an
    encoder); codes and ``limit`` are dimensionless.
    """
    scaled = np.subtract(exact, offset) if offset else np.multiply(exact, 1.0 / step)
    if offset:
        np.multiply(scaled, 1.0 / step, out=scaled)
    np.rint(scaled, out=scaled)  # what np.round does for 0 decimals, without its wrapper
    codes = scaled.astype(integers)
    back = np.multiply(scaled, step, out=scaled)  # the code as a float64 is exact (< 2^53)
    if offset:
        np.add(back, offset, out=back)
    return _Coded(codes, np.logical_and.reduceat(np.equal(back, exact), starts), step, offset,
                  limit)


def coded_by_division(exact: np.ndarray, step: float, offset: float,
                       starts: np.ndarray) -> _Coded:
    """The definition of a float64 channel's codes: ``round((x − offset) / step)`` where it
    fits below 2^53, exact where ``code·step + offset`` gives back ``x``.

    ``step``/``quantum`` and ``offset`` are in the channel's own unit (V for an ADC, deg for an
    encoder); codes and ``limit`` are dimensionless.
    """
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        # x − 0.0 is x bit for bit, so a zero offset is skipped (in place: no temporaries)
        scaled = np.subtract(exact, offset) if offset else exact.copy()
        np.divide(scaled, step, out=scaled)
        np.round(scaled, out=scaled)
        fits = np.abs(scaled) < _MAX_EXACT_CODE  # also False for NaN/inf
        codes = (scaled if fits.all() else np.where(fits, scaled, 0.0)).astype(np.int64)
        # bit for bit, except that −0.0 may come back as +0.0: the one value an integer code
        # cannot carry is the sign of a zero (a rounded encoder reading just below 0), the
        # same physical value in every computation the analyses make. For finite floats, ==
        # is exactly that (equal bits, or two zeros); a value that does not fit is never
        # finite-and-equal. Where it fits, ``scaled`` is the code as a float64 exactly (a
        # whole number below 2^53), up to the sign of a zero: it stands in for
        # codes.astype(float64), one pass and one temporary fewer.
        back = np.multiply(scaled, step, out=scaled)
        if offset:  # (+ 0.0 only turns −0.0 into +0.0, which == does not see)
            np.add(back, offset, out=back)
    same = np.equal(back, exact, out=fits, where=fits)  # stays False where it does not fit
    return _Coded(codes, np.logical_and.reduceat(same, starts), step, offset)


#: serialised field keys written by hand (proto.py numbers)
_PACKED_KEY, _VALUES_KEY = proto.tag(_PACKED_FIELD), proto.tag(_VALUES_FIELD)


@dataclass(frozen=True)
class _Choice:
    """Per block of an exact channel: delta-coded or not, code width; and the chosen codes
    as byte planes of the widest width, block after block (a block of ``n`` codes starting
    at sample ``s`` is ``widest·n`` bytes from ``widest·s`` on, its row ``b`` byte ``b`` of
    every code, little-endian two's complement)."""

    delta: list[bool]
    widths: list[int]
    planes: np.ndarray  # uint8, widest width × samples, block after block
    widest: int


def _choose(codes: np.ndarray, starts: np.ndarray, exact: list[bool],
            limit: float = float("inf"), bounds: list[int] | None = None) -> _Choice:
    """Delta or plain codes per block (the smaller sum of magnitudes), each block's width,
    and the byte planes, in whole-array steps over a pass of blocks.

    Why planes of the widest width serve every block: a code that fits ``w`` bytes has the
    same low ``w`` bytes in any wider two's complement, so a block of width ``w`` is its first
    ``w`` rows, one run of bytes (the planes are laid out block after block: one piece of a
    message, not ``w``). The planes are cut by shifts of the narrow integers, which reads
    memory in order (a transposed copy of the bytes is 2–3× slower). ``bounds``: the blocks'
    first samples and the end, if the caller has them as a list.
    """
    if bounds is None:
        bounds = [*starts.tolist(), codes.size]
    lengths = list(map(sub, bounds[1:], bounds[:-1]))
    longest = max(lengths)
    # a block's sum of |codes| or |differences| is below 2·limit·longest: int32 sums of int32
    # codes are exact below 2^31 and 4× faster than int64 ones (NumPy widens int32 otherwise)
    sums = np.int32 if codes.dtype == np.int32 and 2.0 * limit * longest < 2**31 else np.int64
    steps = np.empty_like(codes)
    np.subtract(codes[1:], codes[:-1], out=steps[1:])
    steps[starts] = codes[starts]  # each block's first difference is from 0
    magnitude = np.abs(codes)
    code_sum = np.add.reduceat(magnitude, starts, dtype=sums)
    step_magnitude = np.abs(steps)
    delta = np.add.reduceat(step_magnitude, starts, dtype=sums) < code_sum
    choices = delta.tolist()  # (a few blocks: Python's all/any cost less than NumPy's)
    top = np.maximum.reduceat(step_magnitude, starts)
    if not all(choices):  # the codes' own top only where they are stored (rarely)
        top = np.where(delta, top, np.maximum.reduceat(magnitude, starts))
    del magnitude, step_magnitude
    chosen = steps if all(choices) else codes if not any(choices) else np.where(
        np.repeat(delta, lengths), steps, codes)
    # each block's width: the narrowest whose signed integers hold every code of magnitude
    # ≤ its top (codes are below 2^53: the widest always does); inline, as a call per block
    # costs more than the comparisons
    widths = [1 if t < 1 << 7 else 2 if t < 1 << 15 else 4 if t < 1 << 31 else 8
              for t in top.tolist()]
    widest = max(widths) if all(exact) else max(compress(widths, exact))
    # codes of blocks that are not exact may not fit: their bytes are never used (no copy
    # when the codes are of the widest width already)
    narrow = chosen.astype(_NARROW[widest], copy=False).view(_UNSIGNED[widest])
    planes = narrow.view(np.uint8) if widest == 1 else _planes(narrow, bounds, lengths,
                                                                widest)
    return _Choice(choices, widths, planes, widest)


def _planes(narrow: np.ndarray, bounds: list[int], lengths: list[int], widest: int
            ) -> np.ndarray:
    """The byte planes of ``narrow`` (unsigned, ``widest`` bytes) block after block: the
    leading blocks of equal length in one strided pass per byte, any others one by one
    (``lengths``: the blocks' lengths, ``bounds``: their first samples and the end)."""
    planes = np.empty(widest * narrow.size, dtype=np.uint8)
    size = lengths[0]
    equal = lengths.count(size)
    if equal < len(lengths):  # a block of another length: the leading run ends before it
        equal = next(i for i, length in enumerate(lengths) if length != size)
    runs = [(bounds[0], equal, size)] + [(a, 1, b - a) for a, b in pairwise(bounds[equal:])]
    for first, blocks, length in runs:
        source = narrow[first:first + blocks * length].reshape(blocks, length)
        rows = planes[widest * first:widest * (first + blocks * length)].reshape(
            blocks, widest, length)
        rows[:, 0, :] = source  # the low byte (a truncating cast)
        for byte in range(1, widest):  # the shifted bytes, cast straight into their rows
            np.right_shift(source, 8 * byte, out=rows[:, byte, :], casting="unsafe")
    return planes


#: samples a pass of :class:`ChannelEncoder` codes at once (whole blocks, at least one). Why
#: not the whole channel: a pass makes ≈ 7 whole-array steps over the values, their codes,
#: differences and magnitudes (≈ 30 bytes a sample); 16 blocks of 4096 samples keep most of
#: them in a core's L2 cache, where 2^17 samples spilled it at every step. Why not fewer:
#: a pass costs ≈ 40 µs of NumPy calls whatever its length (measured with
#: bench/step_writer.py: 8 and 32 blocks a pass were slower)
_PASS_SAMPLES = 65_536


@dataclass(frozen=True)
class _Pass:
    """A coding pass: blocks ``first … stop − 1``, samples ``origin … end − 1`` of a channel,
    and its blocks' first samples counted from ``origin`` (an array, and a list with ``end``)."""

    first: int
    stop: int
    origin: int
    end: int
    starts: np.ndarray
    bounds: list[int]
    #: the blocks' lengths, as a list and as a (read-only) array
    lengths: list[int]
    lengths_array: np.ndarray


@lru_cache(maxsize=256)
def _passes(bounds: tuple[int, ...]) -> tuple[_Pass, ...]:
    """Consecutive passes over blocks ``bounds[b] … bounds[b + 1]``: as many whole blocks as
    fit :data:`_PASS_SAMPLES`, at least one (memoised: every channel of a log, and most logs
    of a run, have the same blocks; the arrays are read-only)."""
    passes, first = [], 0
    while first < len(bounds) - 1:
        stop = first + 1
        while stop < len(bounds) - 1 and bounds[stop + 1] - bounds[first] <= _PASS_SAMPLES:
            stop += 1
        origin = bounds[first]
        relative = [b - origin for b in bounds[first:stop + 1]]
        starts = np.array(relative[:-1], dtype=np.intp)
        lengths = list(map(sub, relative[1:], relative[:-1]))
        lengths_array = np.array(lengths, dtype=np.intp)
        starts.flags.writeable = lengths_array.flags.writeable = False
        passes.append(_Pass(first, stop, origin, bounds[stop], starts, relative, lengths,
                            lengths_array))
        first = stop
    return tuple(passes)


class ChannelEncoder:
    """Serialised ``Channel`` messages of one channel, block by block, built from whole arrays.

    Codes where exact (delta-coded where that is smaller: smooth signals, counters), else
    float64 values; the codes, widths and byte planes are found by vectorised passes over a
    few blocks at a time (:data:`_PASS_SAMPLES`; every choice is per block, so passes give
    the bytes one pass over the whole channel gives). The scalar fields (``name``, ``unit``,
    ``dtype``, ``quantum``, ``offset``, ``delta``, ``width``, ``shuffled``) are serialised by
    protobuf, so each message is byte for byte what ``SerializeToString`` gives.
    """

    def __init__(self, name: str, unit: str, values: np.ndarray,
                 quantum: tuple[float, float] | None, starts: np.ndarray) -> None:
        channel = proto.channel_class()
        self._values = values
        self._channel = channel
        self._head = _serialised(channel, name=name, unit=unit, dtype=values.dtype.str)
        self._bounds: list[int] = np.append(starts, values.size).tolist()
        self._exact: list[bool] = []
        self._delta: list[bool] = []
        self._widths: list[int] = []
        #: per block: the byte planes of its pass, the pass's first sample and widest width
        self._planes: list[tuple[memoryview, int, int] | None] = []
        step_offset = (1.0, 0.0)
        for part in _passes(tuple(self._bounds)):
            chunk = values[part.origin:part.end]
            extremes = _extremes(chunk) if chunk.dtype == np.float64 else None
            if extremes is not None and extremes[0] == extremes[1]:
                found = coded(chunk[:1], quantum, _FIRST)  # one value stands for all
                self._add_constant(found, part)
            else:
                found = coded(chunk, quantum, part.starts, extremes)
                self._add_pass(found, part)
            step_offset = (found.quantum, found.offset)
        # name to delta (memoised by the floats' bits: a cache keyed by the floats would take
        # an offset of −0.0 for 0.0, equal keys, and they serialise apart)
        self._packed_heads = _packed_heads(channel, self._head, _FLOAT_PAIR.pack(*step_offset))

    @property
    def exact_blocks(self) -> list[bool]:
        """Per block: whether it is stored as codes (True) or as float64 values."""
        return list(self._exact)

    def _add_pass(self, found: _Coded, part: _Pass) -> None:
        """Keep one pass's verdicts, choices and byte planes."""
        exact = found.exact.tolist()
        self._exact += exact
        if not any(exact):
            self._delta += [False] * len(exact)
            self._widths += [WIDTHS[-1]] * len(exact)
            self._planes += [None] * len(exact)
            return
        choice = _choose(found.codes, part.starts, exact, found.limit, part.bounds)
        self._delta += choice.delta
        self._widths += choice.widths
        # a memoryview: slicing and joining it costs a third of a NumPy view
        self._planes += [(choice.planes.data, part.origin, choice.widest)] * len(exact)

    def _add_constant(self, found: _Coded, part: _Pass) -> None:
        """:meth:`_add_pass` for a pass whose values all compare equal (a logger at rest: a
        table standing still, a constant temperature), from ``found``, the coding of its first
        value alone; what :func:`_choose` chooses for it, built without its whole-array steps.

        Why it is the same: codes and verdicts are found value by value, and values that
        compare equal (the same float, or two zeros) give the same code ``c`` and verdict, by
        either route (the route and the width of the integers depend only on the largest
        magnitude, the same for one value as for all). A block of ``n`` such codes has the
        magnitude sum ``n·|c|`` and the difference sum ``|c|`` (its first difference is from
        0, the others 0): delta-coded exactly when ``c ≠ 0`` and ``n > 1``; its top is ``|c|``
        either way, so every block has ``c``'s width. Its bytes are ``c`` then zeros (delta),
        or ``c`` alone (``n = 1``), or all zero (``c = 0``): each block's rows hold ``c``'s
        bytes in their first column and zeros elsewhere.
        """
        code, exact = int(found.codes[0]), bool(found.exact[0])
        lengths = part.lengths
        self._exact += [exact] * len(lengths)
        if not exact:
            self._delta += [False] * len(lengths)
            self._widths += [WIDTHS[-1]] * len(lengths)
            self._planes += [None] * len(lengths)
            return
        top = abs(code)
        width = 1 if top < 1 << 7 else 2 if top < 1 << 15 else 4 if top < 1 << 31 else 8
        planes = np.zeros(width * part.bounds[-1], dtype=np.uint8)
        if code:
            rows = width * part.starts  # each block's first column, row 0
            for byte, value in enumerate(code.to_bytes(width, "little", signed=True)):
                planes[rows + byte * part.lengths_array] = value
        self._delta += [bool(code) and length > 1 for length in lengths]
        self._widths += [width] * len(lengths)
        self._planes += [(planes.data, part.origin, width)] * len(lengths)

    def fields(self, key: bytes) -> Iterator[tuple[list[Any], int]]:
        """:meth:`field` of every block, in order (the per-block lookups made once). A
        generator: a step's blocks of every channel held at once would be thousands of small
        lists, enough to set off the garbage collector (≈ 2 ms a step on the stepped sine)."""
        bounds, heads, channel = self._bounds, self._packed_heads, self._channel
        frames: dict[tuple[bool, int, int], tuple[bytes, bytes]] = {}
        for block, (exact, planes, delta, width) in enumerate(zip(
                self._exact, self._planes, self._delta, self._widths, strict=True)):
            if not exact or planes is None:
                yield self.field(block, key)
                continue
            first = bounds[block]
            samples = bounds[block + 1] - first
            kind = (delta, width, samples)
            frame = frames.get(kind)
            if frame is None:
                frame = frames[kind] = _frame(channel, heads[delta], key, width, samples)
            head, tail = frame
            rows, origin, widest = planes
            start, size = widest * (first - origin), width * samples
            yield [head, rows[start:start + size], tail], len(head) + size + len(tail)

    def parts(self, block: int) -> tuple[list[Any], int]:
        """The serialised ``Channel`` of block number ``block`` as consecutive byte-like
        pieces (joined once, into the whole block), and their length in bytes."""
        return self.field(block, b"")

    def field(self, block: int, key: bytes) -> tuple[list[Any], int]:
        """:meth:`parts` as the field ``key`` of a message: the field key and the message's
        length first, then its pieces; and the whole field's length in bytes. The bytes
        around the samples (key, length, scalar fields) are built once per kind of block."""
        first, last = self._bounds[block], self._bounds[block + 1]
        planes = self._planes[block]
        if self._exact[block] and planes is not None:
            width = self._widths[block]
            head, tail = _frame(self._channel, self._packed_heads[self._delta[block]], key,
                                width, last - first)
            rows, origin, widest = planes
            start, size = widest * (first - origin), width * (last - first)
            return [head, rows[start:start + size], tail], len(head) + size + len(tail)
        raw = np.ascontiguousarray(self._values[first:last], dtype="<f8")
        if not raw.size:
            head = _keyed(key, self._head, 0)
            return [head], len(head)
        head = _keyed(key, b"".join((self._head, _VALUES_KEY, proto.varint(raw.nbytes))),
                      raw.nbytes)
        return [head, raw], len(head) + raw.nbytes


    def message(self, block: int) -> bytes:
        """The serialised ``Channel`` of block number ``block``."""
        return b"".join(self.parts(block)[0])


@lru_cache(maxsize=1024)
def _serialised(channel: Any, **fields: Any) -> bytes:
    """A ``Channel`` holding only ``fields``, serialised (memoised: the same few per run)."""
    return bytes(channel(**fields).SerializeToString())


#: the first samples of a single block at sample 0
_FIRST = np.zeros(1, dtype=np.intp)
_FIRST.flags.writeable = False
#: a channel's quantum and offset as the bytes of two little-endian float64 (a cache key)
_FLOAT_PAIR = struct.Struct("<dd")


@lru_cache(maxsize=1024)
def _packed_heads(channel: Any, head: bytes, step_offset: bytes) -> dict[bool, bytes]:
    """``head`` (a channel's serialised name, unit and dtype) and the serialised quantum,
    offset and delta before ``packed``, per delta (``step_offset``: :data:`_FLOAT_PAIR`
    bytes; memoised: the same few per run)."""
    step, offset = _FLOAT_PAIR.unpack(step_offset)
    return {delta: head + channel(quantum=step, offset=offset, delta=delta).SerializeToString()
            for delta in (False, True)}


@lru_cache(maxsize=1024)
def _frame(channel: Any, head: bytes, key: bytes, width: int, samples: int
           ) -> tuple[bytes, bytes]:
    """The bytes before and after the byte planes of a packed block of ``samples`` codes
    (memoised: every step of a run has the same few kinds of block). ``head``: the channel's
    serialised fields before ``packed`` (name, unit, dtype, quantum, offset, delta)."""
    size = width * samples
    tail = _packing(channel, width, width > 1)
    return _keyed(key, b"".join((head, _PACKED_KEY, proto.varint(size))), size + len(tail)), tail


def _keyed(key: bytes, head: bytes, rest: int) -> bytes:
    """``head`` of a message ``rest`` bytes longer, preceded by its field ``key`` and length
    (as is, without a ``key``)."""
    return b"".join((key, proto.varint(len(head) + rest), head)) if key else head


#: code widths (bytes) of format v3, narrowest first
WIDTHS = (1, 2, 4, 8)
#: per width: the dtypes of its signed and unsigned little-endian integers
_NARROW = {w: np.dtype(f"<i{w}") for w in WIDTHS}
_UNSIGNED = {w: np.dtype(f"<u{w}") for w in WIDTHS}


@cache
def _packing(channel: Any, width: int, shuffled: bool) -> bytes:
    """The serialised ``width`` and ``shuffled`` fields (after ``packed`` in field order)."""
    return bytes(channel(width=width, shuffled=shuffled).SerializeToString())
