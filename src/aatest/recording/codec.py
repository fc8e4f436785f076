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
"""

from __future__ import annotations

from collections.abc import Container, Iterable, Iterator, Mapping
from dataclasses import dataclass
from functools import cache
from itertools import chain
from typing import Any

import numpy as np

from aatest.engine.logs import SampledLog
from aatest.recording import proto

TIME_COLUMN = "time_s"
#: field numbers (proto.py): Channel.values, Channel.packed, SampleBlock.time, .channels
_VALUES_FIELD, _PACKED_FIELD, _TIME_FIELD, _CHANNELS_FIELD = 4, 9, 7, 8
#: largest |code| a float64 carries exactly (2^53)
_MAX_EXACT_CODE = float(2**53)
_ALLOWED_KINDS = "fiub"


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


@dataclass(frozen=True)
class _Coded:
    """One channel of a whole log as codes, and which of its blocks they reproduce exactly."""

    codes: np.ndarray  # int64 (int32 if all fit), one per sample (meaningless inside blocks
    #                    that are not exact)
    exact: np.ndarray  # bool, one per block
    quantum: float
    offset: float


#: ``(max|x| + 2·|offset|) / quantum`` up to which a channel's codes may be found by
#: multiplying with ``1 / quantum`` instead of dividing (:func:`_coded_by_reciprocal`)
_RECIPROCAL_SAFE_CODES = float(2**47)
#: ... up to which every code, and every difference of two, fits an int32: half the memory
#: traffic for the delta choice and the byte planes (codes of ±2^29 differ by < 2^31)
_INT32_SAFE_CODES = float(2**29)


def _coded(values: np.ndarray, quantum: tuple[float, float] | None, starts: np.ndarray) -> _Coded:
    """Integer codes of a whole channel, with each block's verdict: do its codes give back every
    value bit for bit? (The per-block choice of :func:`encode_blocks`, made for all at once.)

    Codes come from :func:`_coded_by_reciprocal` where the channel's magnitude makes it give
    exactly the codes and verdicts of :func:`_coded_by_division` (the definition), else from
    the latter.
    """
    if values.dtype.kind in "iub":
        return _Coded(values.astype(np.int64), np.ones(starts.size, dtype=bool), 1.0, 0.0)
    exact = values.astype(np.float64, copy=False)
    step, offset = quantum if quantum is not None else (1.0, 0.0)
    if not np.isfinite(step) or step <= 0.0 or not np.isfinite(offset):
        return _Coded(np.zeros(values.size, np.int64), np.zeros(starts.size, bool), step, offset)
    ratio = _code_ratio(exact, step, offset)
    if ratio <= _RECIPROCAL_SAFE_CODES:  # False for NaN and inf
        integers = np.int32 if ratio <= _INT32_SAFE_CODES else np.int64
        return _coded_by_reciprocal(exact, step, offset, starts, integers)
    return _coded_by_division(exact, step, offset, starts)


def _code_ratio(exact: np.ndarray, step: float, offset: float) -> float:
    """``(max|x| + 2·|offset|) / step`` of a channel: above every code's magnitude (NaN or
    inf for a channel holding NaN or inf, or none at all)."""
    if exact.size == 0:
        return float("nan")
    top = max(float(exact.max()), -float(exact.min()))
    with np.errstate(over="ignore", invalid="ignore"):
        return (top + 2.0 * abs(offset)) / step


def _reciprocal_is_exact(exact: np.ndarray, step: float, offset: float) -> bool:
    """Whether rounding ``(x − offset)·(1/step)`` gives every code :func:`_coded_by_division`
    finds exact, for every value ``x`` of the channel (``step`` > 0 and ``offset`` finite).

    Why it does when ``(max|x| + 2·|offset|)/step ≤ 2^47``: if ``x = fl(fl(c·step) + offset)``
    for a code ``c``, then ``|c| + |offset|/step < 2^48`` and the float64 roundings of the
    subtraction, of ``1/step`` and of the product move the quotient from ``c`` by at most
    ``5.1·2^-53·2^48 ≈ 0.16`` (and the division's by less): both round to ``c``. A value no
    code gives back fails the check whichever code is tried. So every sample gets the same
    verdict, and every exact one the same code, by either route. NaN or ±inf in the channel
    (or a ratio beyond 2^47) keeps the division.
    """
    return bool(_code_ratio(exact, step, offset) <= _RECIPROCAL_SAFE_CODES)


def _coded_by_reciprocal(exact: np.ndarray, step: float, offset: float, starts: np.ndarray,
                         integers: type[np.signedinteger[Any]] = np.int64) -> _Coded:
    """:func:`_coded_by_division` for a channel :func:`_reciprocal_is_exact` accepts: one
    multiplication for the division (a third of its cost), and no test of which codes fit
    (all are below 2^48). ``integers``: the dtype of the codes (int32 when they fit)."""
    scaled = np.subtract(exact, offset) if offset else np.multiply(exact, 1.0 / step)
    if offset:
        np.multiply(scaled, 1.0 / step, out=scaled)
    np.round(scaled, out=scaled)
    codes = scaled.astype(integers)
    back = np.multiply(scaled, step, out=scaled)  # the code as a float64 is exact (< 2^53)
    if offset:
        np.add(back, offset, out=back)
    return _Coded(codes, np.logical_and.reduceat(np.equal(back, exact), starts), step, offset)


def _coded_by_division(exact: np.ndarray, step: float, offset: float,
                       starts: np.ndarray) -> _Coded:
    """The definition of a float64 channel's codes: ``round((x − offset) / step)`` where it
    fits below 2^53, exact where ``code·step + offset`` gives back ``x``."""
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
_TIME_KEY, _CHANNELS_KEY = proto.tag(_TIME_FIELD), proto.tag(_CHANNELS_FIELD)


@dataclass(frozen=True)
class _Choice:
    """Per block of an exact channel: delta-coded or not, code width; and the chosen codes
    of the whole channel as byte planes of the widest width (row ``b``: byte ``b`` of every
    code, little-endian two's complement)."""

    delta: list[bool]
    widths: list[int]
    planes: np.ndarray  # uint8, (widest width, samples)


def _choose(codes: np.ndarray, starts: np.ndarray, exact: list[bool]) -> _Choice:
    """Delta or plain codes per block (the smaller sum of magnitudes), each block's width,
    and the byte planes, in whole-channel passes.

    Why planes of the widest width serve every block: a code that fits ``w`` bytes has the
    same low ``w`` bytes in any wider two's complement, so a block of width ``w`` is rows
    ``0 … w−1`` of its columns; the planes are cut by shifts of the narrow integers, which
    reads memory in order (a transposed copy of the bytes is 2–3× slower).
    """
    steps = np.empty_like(codes)
    np.subtract(codes[1:], codes[:-1], out=steps[1:])
    steps[starts] = codes[starts]  # each block's first difference is from 0
    magnitude = np.abs(codes)
    code_sum = np.add.reduceat(magnitude, starts, dtype=np.int64)  # exact for int32 too
    code_top = np.maximum.reduceat(magnitude, starts)
    np.abs(steps, out=magnitude)
    delta = np.add.reduceat(magnitude, starts, dtype=np.int64) < code_sum
    top = np.where(delta, np.maximum.reduceat(magnitude, starts), code_top)
    del magnitude
    chosen = steps if delta.all() else codes if not delta.any() else np.where(
        np.repeat(delta, np.diff(np.append(starts, codes.size))), steps, codes)
    widths = [_width(t) for t in top.tolist()]
    widest = max(w for w, ok in zip(widths, exact, strict=True) if ok)
    # codes of blocks that are not exact may not fit: their bytes are never used
    narrow = chosen.astype(f"<i{widest}").view(f"<u{widest}")
    if widest == 1:
        planes = narrow.view(np.uint8).reshape(1, -1)
    else:
        planes = np.empty((widest, codes.size), dtype=np.uint8)
        planes[0] = narrow  # the low byte (a truncating cast)
        for byte in range(1, widest):
            planes[byte] = narrow >> (8 * byte)
    return _Choice(delta.tolist(), widths, planes)


class _ChannelEncoder:
    """Serialised ``Channel`` messages of one channel, block by block, built from whole arrays.

    Codes where exact (delta-coded where that is smaller: smooth signals, counters), else
    float64 values; the codes, widths and byte planes of every block are found in one
    vectorised pass. The scalar fields (``name``, ``unit``, ``dtype``, ``quantum``,
    ``offset``, ``delta``, ``width``, ``shuffled``) are serialised by protobuf, so each
    message is byte for byte what ``SerializeToString`` gives.
    """

    def __init__(self, name: str, unit: str, values: np.ndarray,
                 quantum: tuple[float, float] | None, starts: np.ndarray) -> None:
        channel = proto.channel_class()
        self._values = values
        self._channel = channel
        head = channel(name=name, unit=unit, dtype=values.dtype.str)
        self._head: bytes = head.SerializeToString()
        self._bounds = np.append(starts, values.size).tolist()
        coded = _coded(values, quantum, starts)
        self._exact = coded.exact.tolist()
        self._tails: dict[bool, bytes] = {
            delta: channel(quantum=coded.quantum, offset=coded.offset, delta=delta)
            .SerializeToString() for delta in (False, True)}
        self._choice = _choose(coded.codes, starts, self._exact) if any(self._exact) else None

    def parts(self, block: int) -> tuple[list[Any], int]:
        """The serialised ``Channel`` of block number ``block`` as consecutive byte-like
        pieces (joined once, into the whole block), and their length in bytes."""
        first, last = self._bounds[block], self._bounds[block + 1]
        if self._exact[block] and self._choice is not None:
            width = self._choice.widths[block]
            planes = [self._choice.planes[byte, first:last] for byte in range(width)]
            size = width * (last - first)
            tail = _packing(self._channel, width, width > 1)
            head = b"".join((self._head, self._tails[self._choice.delta[block]], _PACKED_KEY,
                             proto.varint(size)))
            return [head, *planes, tail], len(head) + size + len(tail)
        raw = np.ascontiguousarray(self._values[first:last], dtype="<f8")
        if not raw.size:
            return [self._head], len(self._head)
        head = b"".join((self._head, _VALUES_KEY, proto.varint(raw.nbytes)))
        return [head, raw], len(head) + raw.nbytes

    def message(self, block: int) -> bytes:
        """The serialised ``Channel`` of block number ``block``."""
        return b"".join(self.parts(block)[0])


#: code widths (bytes) of format v3, narrowest first
_WIDTHS = (1, 2, 4, 8)


def _width(top: int) -> int:
    """The narrowest width whose signed integers hold every code of magnitude ≤ ``top`` (codes
    are below 2^53: the widest always does)."""
    return next((w for w in _WIDTHS[:-1] if top < 1 << (8 * w - 1)), _WIDTHS[-1])


@cache
def _packing(channel: Any, width: int, shuffled: bool) -> bytes:
    """The serialised ``width`` and ``shuffled`` fields (after ``packed`` in field order)."""
    return bytes(channel(width=width, shuffled=shuffled).SerializeToString())


def check_dtypes(log: SampledLog) -> None:
    """Refuse channels a block cannot carry (complex, strings, objects)."""
    for name, values in log.channels.items():
        if values.dtype.kind not in _ALLOWED_KINDS:
            raise TypeError(f"channel {name!r} has unsupported dtype {values.dtype}")
    if TIME_COLUMN in log.channels:
        raise ValueError(f"{log.source} log has a channel named {TIME_COLUMN!r}")


def _header_parts(header: Mapping[str, object]) -> tuple[dict[str, object], dict[str, object]]:
    """``header`` split into the block fields serialised before the channels and after them."""
    numbers = {f.name: f.number for f in proto.block_class().DESCRIPTOR.fields}
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
    all blocks are computed on whole channels at once (:class:`_ChannelEncoder`).
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
    time = _ChannelEncoder(TIME_COLUMN, "s", log.time_s, declared.get(TIME_COLUMN), starts)
    channels = [_ChannelEncoder(name, str(log.units.get(name, "")), values, declared.get(name),
                                starts) for name, values in log.channels.items()]
    before, after = _header_parts(header)
    block_type = proto.block_class()
    for sequence, log_time_ns in enumerate(log_times_ns):
        head = block_type(sequence=first_sequence + sequence,
                          first_sample=first_sample + int(starts[sequence]), **before)
        tail = block_type(log_time_ns=log_time_ns, **after)
        parts = [head.SerializeToString()]
        for key, encoder in ((_TIME_KEY, time), *((_CHANNELS_KEY, c) for c in channels)):
            pieces, size = encoder.parts(sequence)
            parts += (key, proto.varint(size), *pieces)
        parts.append(tail.SerializeToString())
        yield b"".join(parts)  # the one copy of the samples into the message


def channel_values(message: Any) -> tuple[np.ndarray, tuple[float, float] | None]:
    """One ``Channel`` message → (values in the logged dtype, (quantum, offset) or None).

    Values, quantum and offset are in the channel's own unit (e.g. V, deg, s). Codes may be
    ``packed`` (v3) or varint ``codes`` (v2); a message holds one of the three kinds.
    """
    dtype = np.dtype(message.dtype)
    if dtype.kind not in _ALLOWED_KINDS or dtype.byteorder == ">":
        raise ValueError(f"channel {message.name!r} has unsupported dtype {dtype}")
    packed, codes, values = message.packed, message.codes, message.values
    if (len(packed) > 0) + (len(codes) > 0) + (len(values) > 0) > 1:
        raise ValueError(f"channel {message.name!r} has more than one of packed, codes, values")
    if not packed and not len(codes):
        return np.array(values, dtype=np.float64).astype(dtype), None
    quantum = (float(message.quantum), float(message.offset))
    integers = _unpacked(message) if packed else np.array(codes, dtype=np.int64)
    if message.delta:
        integers = np.cumsum(integers, dtype=np.int64)
    return decode_codes(integers, *quantum, dtype), quantum


def _unpacked(message: Any) -> np.ndarray:
    """The integers of a v3 ``packed`` field, in their stored width (no copy unless shuffled)."""
    width = int(message.width)
    packed = message.packed
    if width not in _WIDTHS or len(packed) % width:
        raise ValueError(f"channel {message.name!r}: {len(packed)} packed bytes do not "
                         f"make codes of width {width}")
    raw = np.frombuffer(packed, dtype=np.uint8)
    if message.shuffled and width > 1:
        # byte planes → one row of bytes per code, a plane at a time: NumPy copies each plane
        # with a unit-stride read, where a transposed copy of the whole (3–4× slower) walks
        # rows of 2–8 bytes
        planes = raw.reshape(width, -1)
        rows = np.empty((planes.shape[1], width), dtype=np.uint8)
        for byte, plane in enumerate(planes):
            rows[:, byte] = plane
        raw = rows.reshape(-1)
    return raw.view(f"<i{width}")


def _decoded_into(message: Any, out: np.ndarray) -> bool:
    """Decode a packed float64 channel straight into ``out`` (float64, its block's samples):
    :func:`decode_codes` of its codes (cumulated when delta-coded), in place. False, with
    nothing written, for any other kind of message (:func:`channel_values` decodes it).

    Why: a block's channel is a few thousand samples, so decoding it is mostly per-call
    overhead; summing the codes straight into the column in float64 and scaling in place
    makes four NumPy calls of the nine, and no temporaries. The sums are the very ones of
    the int64 path: every running sum of whole numbers below 2^53 is exact in float64, and
    codes of ``width`` bytes over a block of fewer than 2^(54 − 8·width) samples cannot
    reach it (wider codes or longer blocks take the int64 path).
    """
    if (not message.packed or out.dtype != np.float64 or message.dtype != _FLOAT64
            or len(message.codes) or len(message.values)):
        return False
    codes = _unpacked(message)
    if codes.size != out.size:
        return False
    if message.delta:
        if codes.itemsize == _WIDTHS[-1] or codes.size >= 1 << (54 - 8 * codes.itemsize):
            return False
        np.cumsum(codes, dtype=np.float64, out=out)
    else:
        out[...] = codes  # the int → float64 conversion astype makes
    out *= float(message.quantum)
    out += float(message.offset)
    return True


#: the dtype string of a float64 channel as the writer stores it
_FLOAT64 = np.dtype(np.float64).str


def samples_in(message: Any) -> int:
    """The number of samples a ``Channel`` message holds (whichever way they are stored)."""
    if message.packed:
        return len(message.packed) // max(int(message.width), 1)
    return len(message.codes) or len(message.values)


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
    size = samples_in(block.time)
    start = int(block.first_sample)
    if start + size > samples:
        raise ValueError(f"has more samples than the {samples} its step record says")
    for message in (block.time, *block.channels):
        column = columns.get(message.name)
        if column is None:
            continue
        into = column[start - origin:start - origin + size]
        if into.size == size and _decoded_into(message, into):
            continue
        values, _ = channel_values(message)
        if values.size != size:
            raise ValueError(f"channel {message.name!r} has {values.size} samples in "
                             f"block {block.sequence}, time has {size}")
        if values.dtype != column.dtype:
            raise ValueError(f"channel {message.name!r} changes dtype between blocks")
        into[...] = values
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
