"""Blocks decoded together (a channel's blocks of every width at once) equal the blocks decoded
one by one, bit for bit, whatever their order, widths, count and scaling.

:func:`aatest.recording.codec.blocks_to_log` batches a log's blocks
(:mod:`aatest.recording.block_runs`); :func:`~aatest.recording.codec.channel_values` decodes a
single ``Channel`` message by the int64 path. Their outputs must be the same bytes, the sign of
a zero included.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from aatest.recording import proto
from aatest.recording.codec import blocks_to_log, channel_values

BLOCK = 512


def _packed(codes: np.ndarray, width: int) -> bytes:
    """``codes`` as little-endian integers of ``width`` bytes, as byte planes when wider."""
    raw = codes.astype(f"<i{width}").view(np.uint8).reshape(-1, width)
    return raw.T.tobytes() if width > 1 else raw.tobytes()


def _channel(name: str, stored: np.ndarray, width: int, delta: bool, quantum: float,
             offset: float, dtype: str = "<f8") -> Any:
    return proto.channel_class()(name=name, unit="V", dtype=dtype, quantum=quantum,
                                 offset=offset, delta=delta, packed=_packed(stored, width),
                                 width=width, shuffled=width > 1)


def _width(stored: np.ndarray) -> int:
    top = int(np.abs(stored).max()) if stored.size else 0
    return next(w for w in (1, 2, 4, 8) if top < 1 << (8 * w - 1))


#: (name, dtype, quantum, offset): an ADC with an offset, a zero offset, a negative quantum
#: with +0.0 and −0.0 offsets (where −0.0 products must come out as channel_values gives
#: them), an integer channel (the int64 path), and +0.0 and −0.0 offsets in turn
CHANNELS = [("v", "<f8", 20.0 / 2**16, -10.0), ("deg", "<f8", 1 / 3600.0, 0.0),
            ("neg", "<f8", -0.5, 0.0), ("negz", "<f8", -0.5, -0.0), ("count", "<i4", 1.0, 0.0),
            ("flip", "<f8", -0.5, float("nan"))]  # offset +0.0 and −0.0 block after block


def _blocks(rng: np.random.Generator, sizes: list[int]) -> list[Any]:
    """Blocks of random codes per channel, each block's codes of a random magnitude (so its
    width differs from its neighbours'), delta-coded or not at random."""
    blocks, first = [], 0
    for sequence, size in enumerate(sizes):
        block = proto.block_class()(sequence=sequence, first_sample=first, source="daq")
        block.time.CopyFrom(_channel("time_s", np.arange(size) + first, 4, False, 1e-3, 0.0))
        for name, dtype, quantum, offset in CHANNELS:
            top = int(rng.choice([3, 100, 20_000, 2**20]))
            codes = rng.integers(-top, top, size, endpoint=True)
            delta = bool(rng.integers(2))
            if name == "flip":  # zero codes (−0.0 products) in blocks alike but for the offset
                codes, delta = codes % 3 - 1, False
                offset = -0.0 if sequence % 2 else 0.0  # noqa: PLW2901 - per block
            stored = np.diff(codes, prepend=np.int64(0)) if delta else codes
            block.channels.add().CopyFrom(
                _channel(name, stored, _width(stored), delta, quantum, offset, dtype))
        blocks.append(block)
        first += size
    return blocks


@pytest.mark.parametrize("count", [1, 2, 7, 16])
def test_batched_decode_equals_block_by_block_in_any_order(count: int) -> None:
    rng = np.random.default_rng(count)
    sizes = [BLOCK] * count + [BLOCK // 3]  # a short last block, as a log's end has
    blocks = _blocks(rng, sizes)
    expected = {name: np.concatenate([channel_values(next(
        c for c in b.channels if c.name == name))[0] for b in blocks])
        for name, *_ in CHANNELS}
    order = rng.permutation(len(blocks))
    log = blocks_to_log([blocks[k] for k in order], "daq", 1000.0, sum(sizes), {})
    for name, dtype, *_ in CHANNELS:
        assert log[name].dtype == np.dtype(dtype)
        assert log[name].tobytes() == expected[name].tobytes(), name
    assert log.time_s.tobytes() == (np.arange(sum(sizes)) * 1e-3).tobytes()


def test_a_block_whose_channel_is_short_is_refused_naming_it() -> None:
    blocks = _blocks(np.random.default_rng(3), [BLOCK, BLOCK])
    short = blocks[1].channels[0]
    short.packed = short.packed[:short.width * (BLOCK - 1)] if short.width == 1 else \
        _packed(np.zeros(BLOCK - 1, np.int64), short.width)
    with pytest.raises(ValueError, match=r"channel 'v' has 511 samples in block 1, time has 512"):
        blocks_to_log(blocks, "daq", 1000.0, 2 * BLOCK, {})
