"""The vectorised block encoder writes exactly what the protobuf API serialises.

The reference here fills every ``SampleBlock`` through the protobuf API, one block and one
channel at a time, with the coding rules of :mod:`aatest.recording.codec` (codes where
they give back every value bit for bit, delta-coded when smaller, else float64 values); the
encoder must produce the same bytes, so any protobuf reader decodes it the same way. Format
v3 stores the codes as ``packed`` fixed-width integers; a v2 message (varint ``codes``) still
decodes to the same values.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from aatest.engine.logs import SampledLog
from aatest.recording import proto
from aatest.recording.codec import blocks_to_log, encode_blocks

BLOCK = 4096
LSB_V = 20.0 / 2**16


def _reference_channel(message: Any, name: str, unit: str, values: np.ndarray,
                       quantum: tuple[float, float] | None) -> None:
    """One block's channel through the protobuf API (codes only where exact)."""
    message.name, message.unit, message.dtype = name, unit, values.dtype.str
    if values.dtype.kind in "iub":
        codes, step, offset = values.astype(np.int64), 1.0, 0.0
    else:
        step, offset = quantum if quantum is not None else (1.0, 0.0)
        exact = values.astype(np.float64)
        with np.errstate(invalid="ignore", over="ignore"):
            scaled = np.round((exact - offset) / step) if np.isfinite(step) and step > 0 \
                else np.full(exact.size, np.nan)
        ok = bool(np.all(np.abs(scaled) < 2.0**53))
        codes = scaled.astype(np.int64) if ok else np.zeros(0, np.int64)
        back = codes.astype(np.float64) * step + offset
        if not ok or not np.array_equal(np.where(exact == 0, 0.0, exact).view(np.uint64),
                                        back.view(np.uint64)):
            message.values.extend(exact.tolist())
            return
    diffs = np.diff(codes, prepend=np.int64(0))
    message.delta = bool(np.abs(diffs).sum() < np.abs(codes).sum())
    message.packed, message.width, message.shuffled = _packed(
        (diffs if message.delta else codes).tolist())
    message.quantum, message.offset = step, offset


def _packed(codes: list[int]) -> tuple[bytes, int, bool]:
    """Format v3's ``packed`` codes, one Python int at a time: little-endian two's complement
    of the narrowest width that holds them all, as byte planes when wider than a byte."""
    top = max(abs(c) for c in codes)
    width = next(w for w in (1, 2, 4, 8) if top < 2 ** (8 * w - 1) or w == 8)
    rows = [c.to_bytes(width, "little", signed=True) for c in codes]
    if width == 1:
        return b"".join(rows), width, False
    return bytes(row[plane] for plane in range(width) for row in rows), width, True


def _reference_blocks(log: SampledLog, header: dict[str, Any], times_ns: list[int]) -> list[bytes]:
    out = []
    for sequence, t_ns in enumerate(times_ns):
        part = slice(sequence * BLOCK, (sequence + 1) * BLOCK)
        block = proto.block_class()(sequence=sequence, first_sample=part.start,
                                    log_time_ns=t_ns, **header)
        _reference_channel(block.time, "time_s", "s", log.time_s[part],
                           log.quantisation.get("time_s"))
        for name, values in log.channels.items():
            _reference_channel(block.channels.add(), name, log.units.get(name, ""),
                               values[part], log.quantisation.get(name))
        out.append(block.SerializeToString())
    return out


def _mixed_log(n: int, seed: int) -> SampledLog:
    """Every case the coder distinguishes: ADC codes on and off the grid, −0.0 encoder counts,
    NaN/inf, huge codes, ints, bools, uint8, float32, noise, a bad declared quantum."""
    rng = np.random.default_rng(seed)
    adc = np.round(rng.normal(0, 1, n) / LSB_V) * LSB_V - 10.0 + 10.0
    off_grid = adc.copy()
    off_grid[min(BLOCK + 7, n - 1)] += LSB_V / 3
    q_deg = 0.01 / 3600
    counts = np.round(rng.normal(0, 3 * q_deg, n) / q_deg) * q_deg
    bad = adc.copy()
    bad[min(5, n - 1)], bad[-1] = np.nan, np.inf
    channels = {
        "adc": adc, "off_grid": off_grid, "counts": counts, "bad": bad,
        "huge": np.round(rng.normal(0, 1e17, n)), "ints": rng.integers(-2**40, 2**40, n),
        "bools": rng.random(n) > 0.5, "bytes": rng.integers(0, 255, n).astype(np.uint8),
        "single": rng.normal(0, 1, n).astype(np.float32), "noise": rng.normal(0, 1, n),
        "ramp": np.cumsum(rng.integers(-3, 4, n)) * 0.001, "nan_quantum": adc.copy(),
        # blocks of width 1, 2, 4 and 8 in one channel (they share its byte planes), plain
        # noise then a delta-coded drift, with an off-grid block between
        "widening": np.round(rng.normal(0, 1, n) * 1e3 ** (np.arange(n) // BLOCK)) * 0.5,
        "drift": (np.cumsum(rng.integers(-2, 3, n)) + 7**(np.arange(n) // BLOCK * 6)) * 0.25,
    }
    if n > BLOCK:
        channels["widening"][BLOCK + 1] += 0.1
    quanta = {"adc": (LSB_V, -10.0), "off_grid": (LSB_V, -10.0), "counts": (q_deg, 0.0),
              "bad": (LSB_V, 0.0), "ramp": (0.001, 0.0), "nan_quantum": (float("nan"), 0.0),
              "time_s": (1 / 2000, 0.0), "widening": (0.5, 0.0), "drift": (0.25, 0.0)}
    return SampledLog("daq", 2000.0, np.arange(n) / 2000.0, channels,
                      {"adc": "V", "counts": "deg"}, quanta)


HEADER = {"step_id": "s1", "step_index": 3, "source": "daq", "sample_rate_hz": 2000.0,
          "step_record_sha256": "ab" * 32}


@pytest.mark.parametrize("n", [1, BLOCK, 3 * BLOCK + 5], ids=["one", "one-block", "short-last"])
@pytest.mark.parametrize("header", [{}, HEADER], ids=["bare", "header"])
def test_encoder_bytes_equal_the_protobuf_api(n: int, header: dict[str, Any]) -> None:
    log = _mixed_log(n, seed=n)
    times_ns = [10**9 * k for k in range(-(-n // BLOCK))]
    assert list(encode_blocks(log, header, BLOCK, times_ns)) == \
        _reference_blocks(log, header, times_ns)


def test_encoded_blocks_decode_bit_exact() -> None:
    log = _mixed_log(2 * BLOCK + 3, seed=9)
    messages = [proto.block_class().FromString(b)
                for b in encode_blocks(log, {"source": "daq"}, BLOCK, [0, 1, 2])]
    back = blocks_to_log(messages, "daq", 2000.0, len(log), dict(log.quantisation))
    for name, values in log.channels.items():
        got = back[name]
        assert got.dtype == values.dtype
        keep = values != 0  # −0.0 comes back as +0.0 (the same number)
        assert got[keep].tobytes() == values[keep].tobytes(), name
        assert np.all(got[~keep] == 0), name


def test_encoder_refuses_log_times_that_do_not_match_the_blocks() -> None:
    with pytest.raises(ValueError, match="2 block log times for 1 blocks"):
        list(encode_blocks(_mixed_log(10, seed=1), {}, BLOCK, [0, 1]))


@pytest.mark.parametrize("codes", [[0, 1, -1, 127, -127], [128, -129, 5], [2**31 - 1, -2**31],
                                   [2**31, -5], [2**53, -2**53, 0]],
                         ids=["int8", "int16", "int32", "int64", "float64-limit"])
def test_packed_codes_of_every_width_decode_as_v2_varints_do(codes: list[int]) -> None:
    """A channel's codes as v3 ``packed`` (each width, byte planes) and as v2 varint
    ``codes`` decode to the same values; the widths are the narrowest that hold the codes."""
    from aatest.recording.codec import channel_values

    channel = proto.channel_class()
    head = {"name": "x", "unit": "V", "dtype": "<f8", "quantum": LSB_V, "offset": -10.0}
    packed, width, shuffled = _packed(codes)
    assert width == {"int8": 1, "int16": 2, "int32": 4}.get(_width_name(codes), 8)
    v3, _ = channel_values(channel(packed=packed, width=width, shuffled=shuffled, **head))
    v2, _ = channel_values(channel(codes=codes, **head))
    assert v3.tobytes() == v2.tobytes() == (np.array(codes) * LSB_V - 10.0).tobytes()


def _width_name(codes: list[int]) -> str:
    top = max(abs(c) for c in codes)
    return "int8" if top < 2**7 else "int16" if top < 2**15 else "int32" if top < 2**31 else ""


@pytest.mark.parametrize("width, size", [(3, 6), (2, 5)], ids=["bad-width", "ragged"])
def test_packed_codes_of_a_bad_width_are_refused(width: int, size: int) -> None:
    from aatest.recording.codec import channel_values

    message = proto.channel_class()(name="x", dtype="<f8", packed=bytes(size), width=width)
    with pytest.raises(ValueError, match="packed bytes do not make codes of width"):
        channel_values(message)


def test_encoder_bytes_equal_the_protobuf_api_across_coding_passes() -> None:
    """A channel longer than one coding pass (:data:`channel_codes._PASS_SAMPLES`): each pass
    chooses its own route (codes by the reciprocal in int32 or int64, or by the division)
    and its own byte planes; the blocks are still the protobuf API's, block by block."""
    from aatest.recording.channel_codes import _PASS_SAMPLES

    n = _PASS_SAMPLES + 2 * BLOCK + 5  # a whole pass, then two blocks and five samples
    log = _mixed_log(n, seed=4)
    rng = np.random.default_rng(4)
    late = np.arange(n) >= _PASS_SAMPLES
    small = rng.integers(-100, 100, n).astype(np.float64)
    channels = {
        **log.channels,
        # int32 codes in the first pass, codes near 2^50 (the division) in the second
        "late_huge": np.where(late, small + 2.0**50, small) * 0.5,
        # int64 codes (beyond 2^29) in the first pass, int32 ones in the second
        "early_wide": np.where(late, small, small + 2.0**40) * 0.5,
    }
    quanta = {**log.quantisation, "late_huge": (0.5, 0.0), "early_wide": (0.5, 0.0)}
    log = SampledLog("daq", 2000.0, log.time_s, channels, dict(log.units), quanta)
    times_ns = [10**9 * k for k in range(-(-n // BLOCK))]
    assert list(encode_blocks(log, HEADER, BLOCK, times_ns)) == \
        _reference_blocks(log, HEADER, times_ns)


def test_constant_passes_encode_as_the_protobuf_api_does() -> None:
    """Passes whose values all compare equal take a short cut (the coding of one value stands
    for all): zero, positive and negative codes of every width, −0.0 among 0.0, a value off
    the grid, an offset, inf, a single-sample last block and a channel constant in one pass
    only must still give the protobuf API's blocks, block by block."""
    from aatest.recording.channel_codes import _PASS_SAMPLES

    n = _PASS_SAMPLES + BLOCK + 1  # a whole pass, then a block and a block of one sample
    zeros = np.zeros(n)
    zeros[::3] = -0.0
    late = np.arange(n) >= _PASS_SAMPLES
    channels = {
        "zeros": zeros, "small": np.full(n, 0.75), "negative": np.full(n, -300.25),
        "wide": np.full(n, -(2.0**40) * 0.25), "widest": np.full(n, 2.0**50 * 0.25),
        "off_grid": np.full(n, 0.1), "offset": np.full(n, LSB_V * 1000 - 10.0),
        "inf": np.full(n, np.inf),
        "moves_late": np.where(late, np.arange(n) % 5 * 0.25, 2.5),
        "temperature": np.full(n, 23.0),  # no declared quantum: whole numbers, quantum 1
    }
    quanta = {name: (0.25, 0.0) for name in channels} | {
        "offset": (LSB_V, -10.0), "off_grid": (0.25, 0.0), "time_s": (1 / 2000, 0.0)}
    del quanta["temperature"]
    log = SampledLog("daq", 2000.0, np.arange(n) / 2000.0, channels, {}, quanta)
    times_ns = [10**9 * k for k in range(-(-n // BLOCK))]
    assert list(encode_blocks(log, HEADER, BLOCK, times_ns)) == \
        _reference_blocks(log, HEADER, times_ns)
