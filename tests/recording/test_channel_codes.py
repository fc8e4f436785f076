"""The writer's fast route to a channel's codes gives exactly the codes of the definition.

:func:`aatest.recording.channel_codes.coded` finds a float channel's integer codes by
multiplying with ``1/quantum`` when the channel's magnitude allows it
(:func:`reciprocal_is_exact`), else by the defining division (:func:`coded_by_division`). A
recorded block is bytes of those codes and verdicts, so the two routes must agree on every
block's verdict and on every code of an exact block, for the twin's real logs and for floats
made to sit just off the code grid, on ties, and at the edge of the magnitude bound. These
are exact integer and boolean comparisons: the claim is identity, not closeness.
"""

from __future__ import annotations

import numpy as np
import pytest

from aatest.recording.channel_codes import (
    coded,
    coded_by_division,
    coded_by_reciprocal,
    reciprocal_is_exact,
)
from aatest.twin.api import realistic_rig_model, simulate_dataset

BLOCK = 4096


def _starts(n: int) -> np.ndarray:
    return np.arange(0, n, BLOCK, dtype=np.intp)


def _assert_same_as_division(values: np.ndarray, quantum: float, offset: float) -> None:
    """Both routes: the same verdict per block, the same codes in every exact block."""
    starts = _starts(values.size)
    exact = values.astype(np.float64)
    fast = coded(values, (quantum, offset), starts)
    slow = coded_by_division(exact, quantum, offset, starts)
    np.testing.assert_array_equal(fast.exact, slow.exact)
    bounds = np.append(starts, values.size)
    for block in np.flatnonzero(slow.exact):
        part = slice(bounds[block], bounds[block + 1])
        np.testing.assert_array_equal(fast.codes[part], slow.codes[part])
    assert (fast.quantum, fast.offset) == (slow.quantum, slow.offset)


@pytest.fixture(scope="module")
def twin_logs() -> list:
    """One stepped-sine-like step of the realistic twin (seeded): its table and DAQ logs."""
    from aatest.engine.steps import PlannedStep

    samples = 3 * BLOCK + 123
    step = PlannedStep(id="s1", kind="sine", axis="inner", samples=samples,
                       sample_rate_hz=2000.0, duration_s=samples / 2000.0, frequency_hz=8.0,
                       cycles=49, accel_dps2=400.0,
                       amplitude_deg=400.0 / (2 * np.pi * 8.0) ** 2)
    data = simulate_dataset(realistic_rig_model(), [step], seed=7).steps[0]
    return [data.table, data.daq]


def test_twin_channels_take_the_fast_route_and_match_the_definition(twin_logs: list) -> None:
    fast_channels = 0
    for log in twin_logs:
        declared = dict(log.quantisation)
        for name, values in [("time_s", log.time_s), *log.channels.items()]:
            if values.dtype.kind != "f":
                continue
            quantum, offset = declared.get(name, (1.0, 0.0))
            fast_channels += reciprocal_is_exact(values, quantum, offset)
            _assert_same_as_division(values, quantum, offset)
    # every float channel of the twin is far inside the bound (ADC codes < 2^16, encoder
    # counts < 2^30): a bound that never admits them would test nothing
    assert fast_channels == sum(
        1 + sum(v.dtype.kind == "f" for v in log.channels.values()) for log in twin_logs)


#: (quantum, offset) pairs: an ADC (LSB, low end), an encoder count, a time step, a quantum
#: not exact in binary with a large offset, a tiny quantum
QUANTA = [(20.0 / 2**16, -10.0), (0.01 / 3600, 0.0), (1e-7, 0.0), (0.1, 12345.6),
          (1e-12, -3e-3)]


@pytest.mark.parametrize(("quantum", "offset"), QUANTA)
def test_off_grid_floats_get_the_definitions_verdicts(quantum: float, offset: float) -> None:
    """On the grid, one ulp off it, on ties, half a quantum off, and random: per block."""
    rng = np.random.default_rng(11)
    n = 6 * BLOCK
    codes = rng.integers(-2**20, 2**20, n).astype(np.float64)
    on_grid = codes * quantum + offset
    variants = [
        on_grid,
        np.nextafter(on_grid, np.inf),  # one ulp above: never a code's value
        (codes + 0.5) * quantum + offset,  # ties of the rounding
        on_grid + rng.uniform(-0.5, 0.5, n) * quantum,  # anywhere in the cell
    ]
    mixed = on_grid.copy()
    mixed[BLOCK + 17] = np.nextafter(mixed[BLOCK + 17], -np.inf)  # one bad sample in block 1
    mixed[3 * BLOCK:4 * BLOCK] = variants[2][3 * BLOCK:4 * BLOCK]  # block 3 all ties
    mixed[5 * BLOCK] = -0.0 if offset == 0.0 else mixed[5 * BLOCK]  # a −0.0 code (exact)
    for values in [*variants, mixed]:
        _assert_same_as_division(values, quantum, offset)


def test_codes_at_the_magnitude_bound_match_the_definition() -> None:
    """Codes near 2^46 (just inside the bound), with and without an offset; beyond the
    bound, and with NaN or inf, the division is used."""
    rng = np.random.default_rng(5)
    n = 2 * BLOCK
    quantum = 3.0e-5
    for offset in (0.0, -7.0):
        codes = rng.integers(2**46 - 2**20, 2**46, n) * rng.choice([-1, 1], n)
        values = codes.astype(np.float64) * quantum + offset
        assert reciprocal_is_exact(values, quantum, offset)
        _assert_same_as_division(values, quantum, offset)
        _assert_same_as_division(np.nextafter(values, 0.0), quantum, offset)
    beyond = rng.integers(2**52, 2**53, n).astype(np.float64) * quantum
    assert not reciprocal_is_exact(beyond, quantum, 0.0)
    _assert_same_as_division(beyond, quantum, 0.0)
    # why the bound: there the reciprocal's rounding picks other codes than the division
    starts = _starts(n)
    assert not np.array_equal(coded_by_reciprocal(beyond, quantum, 0.0, starts).exact,
                              coded_by_division(beyond, quantum, 0.0, starts).exact)
    for bad in (np.nan, np.inf, -np.inf):
        values = rng.integers(-100, 100, n) * quantum
        values[3] = bad
        assert not reciprocal_is_exact(values, quantum, 0.0)
        _assert_same_as_division(values, quantum, 0.0)
    assert not reciprocal_is_exact(np.ones(4), 5e-324, 0.0)  # subnormal quantum: ratio inf
    assert not reciprocal_is_exact(np.ones(4) * 1e300, 1e-300, 0.0)


def test_int32_codes_and_sums_choose_what_int64_ones_do() -> None:
    """Codes found as int32 (summed in int32 when the limit allows) give the delta choice,
    widths and byte planes of the same codes in int64, at the edge of the int32-sum limit
    (steps of ±2^19 on every sample) and beyond it (int64 sums)."""
    from aatest.recording.channel_codes import _choose

    rng = np.random.default_rng(3)
    n = 3 * BLOCK + 77
    starts = _starts(n)
    exact = [True] * starts.size
    edge = float(2**18 - 2)  # 2·(limit)·4096 < 2^31: int32 sums
    for limit, codes in [
        (edge, rng.choice([-(2**18 - 3), 2**18 - 3], n)),  # alternating extremes
        (edge, np.cumsum(rng.integers(-3, 4, n)) + 2**17),  # a slow drift: delta-coded
        (float(2**29), rng.integers(-(2**29), 2**29, n)),  # int64 sums
    ]:
        as32 = _choose(codes.astype(np.int32), starts, exact, limit)
        as64 = _choose(codes.astype(np.int64), starts, exact)
        assert as32.delta == as64.delta
        assert as32.widths == as64.widths
        np.testing.assert_array_equal(as32.planes, as64.planes)
