"""The register map's codecs: word order, float widths, bit packing, labels, no overlaps."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from aatest.protocols import modbus_map as mm
from aatest.protocols.modbus_map import Reg


def test_float64_is_abcd_high_word_first() -> None:
    # 1.5 = 0x3FF8000000000000: the first register carries the most significant word
    assert mm.encode(Reg.LOG_T0_S, 1.5) == [0x3FF8, 0, 0, 0]
    assert mm.encode(Reg.LOG_RATE_HZ, 2000.0) == [0x44FA, 0x0000]
    assert mm.encode(Reg.LOG_SAMPLES, 131072) == [0x0002, 0x0000]


@given(st.floats(allow_nan=False, allow_infinity=False, width=64))
def test_f64_round_trip_is_exact(value: float) -> None:
    assert mm.decode(Reg.INNER_POSITION_DEMAND_DEG,
                     mm.encode(Reg.INNER_POSITION_DEMAND_DEG, value)) == value


def test_f32_quantisation_is_within_single_precision() -> None:
    rng = np.random.default_rng(1)
    rates = rng.uniform(-1200, 1200, 500)
    back = mm.decode_array(mm.encode_array(rates, "f32"), "f32")
    np.testing.assert_allclose(back, rates, rtol=6e-8, atol=0)


@given(st.lists(st.integers(0, 1), min_size=1, max_size=200))
def test_bits_round_trip(bits: list[int]) -> None:
    assert mm.decode_bits(mm.encode_bits(np.array(bits)), len(bits)).tolist() == bits


def test_window_round_trip_every_channel() -> None:
    rng = np.random.default_rng(2)
    for channel in mm.LOG_CHANNELS:
        values = rng.integers(0, 2, 500) if channel.encoding == "bits" else rng.normal(0, 90, 500)
        start = 37
        regs = mm.encode_channel_window(values, channel, start)
        assert len(regs) == mm.WINDOW_REGISTERS
        count = min(channel.samples_per_window, values.size - start)
        back = mm.decode_channel_window(regs, channel, count)
        rtol = 6e-8 if channel.encoding == "f32" else 0.0
        np.testing.assert_allclose(back, values[start:start + count], rtol=rtol)


def test_label_round_trip_and_truncation() -> None:
    assert mm.decode_label(mm.encode_label("s07-sine-1.007Hz")) == "s07-sine-1.007Hz"
    assert len(mm.decode_label(mm.encode_label("x" * 50))) == 2 * mm.LABEL_REGISTERS


def test_registers_do_not_overlap_and_fit_fc23() -> None:
    spans = sorted((int(r), int(r) + mm.width(r)) for r in Reg if r not in (Reg.WINDOW,
                                                                          Reg.LOG_LABEL))
    spans += [(Reg.LOG_LABEL, Reg.LOG_LABEL + mm.LABEL_REGISTERS),
              (Reg.WINDOW, Reg.WINDOW + mm.WINDOW_REGISTERS)]
    spans.sort()
    for (a0, a1), (b0, _b1) in itertools.pairwise(spans):
        assert a1 <= b0, (a0, b0)
    assert mm.WINDOW_REGISTERS <= 125


@pytest.mark.parametrize("channel", mm.LOG_CHANNELS, ids=lambda c: c.name)
def test_every_table_channel_is_downloadable(channel: mm.LogChannel) -> None:
    from aatest.engine.logs import TABLE_CHANNELS

    assert channel.name == "time_s" or channel.name in TABLE_CHANNELS
    assert {c.name for c in mm.LOG_CHANNELS} - {"time_s"} == set(TABLE_CHANNELS)
