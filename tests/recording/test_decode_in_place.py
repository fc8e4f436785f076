"""Blocks decoded straight into their columns give the values of the int64 path bit for bit.

:func:`aatest.recording.codec.blocks_to_log` sums a packed float64 channel's delta codes in
float64, in place (exact below 2^53); :func:`~aatest.recording.codec.channel_values` sums them
in int64 and converts once. Every width, delta or not, with codes up to the float64 limit,
must come out the same.
"""

from __future__ import annotations

import numpy as np
import pytest

from aatest.recording import proto
from aatest.recording.codec import blocks_to_log, channel_values

LSB_V = 20.0 / 2**16


def _planes(codes: np.ndarray, width: int) -> bytes:
    """``codes`` as little-endian integers of ``width`` bytes, as byte planes when wider."""
    raw = codes.astype(f"<i{width}").view(np.uint8).reshape(-1, width)
    return raw.T.tobytes() if width > 1 else raw.tobytes()


def _channel(name: str, codes: np.ndarray, width: int, delta: bool) -> object:
    stored = np.diff(codes, prepend=np.int64(0)) if delta else codes
    return proto.channel_class()(
        name=name, unit="V", dtype="<f8", quantum=LSB_V, offset=-10.0, delta=delta,
        packed=_planes(stored, width), width=width, shuffled=width > 1)


@pytest.mark.parametrize("width", [1, 2, 4, 8])
@pytest.mark.parametrize("delta", [False, True], ids=["codes", "delta"])
def test_in_place_decode_equals_the_int64_path(width: int, delta: bool) -> None:
    rng = np.random.default_rng(width)
    n = 3000
    # delta codes fill the width (their running sums, the codes, stay below 2^53)
    top = 2 ** (8 * width - 1) - 1
    if delta:
        steps = rng.integers(-top, top, n, endpoint=True)
        steps[0] = 0
        codes = np.cumsum(steps) if width < 8 else rng.integers(-2**53 + 1, 2**53, n)
    else:
        codes = rng.integers(-min(top, 2**53 - 1), min(top, 2**53 - 1), n, endpoint=True)
    time = proto.channel_class()(name="time_s", dtype="<f8",
                                 values=(np.arange(n) / 2000.0).tolist())
    block = proto.block_class()(sequence=0, first_sample=0, source="daq")
    block.time.CopyFrom(time)
    block.channels.add().CopyFrom(_channel("v", codes, width, delta))
    log = blocks_to_log([block], "daq", 2000.0, n, {})
    expected, _ = channel_values(block.channels[0])
    assert log["v"].tobytes() == expected.tobytes()
    assert log["v"].tobytes() == (codes.astype(np.float64) * LSB_V - 10.0).tobytes()
