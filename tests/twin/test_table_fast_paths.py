"""The table truth's and the noise generator's fast paths give the numbers of their plain forms.

Speed work on the twin must not move a recorded value (a last-bit change flips ADC codes), so
each rewritten stage is pinned bit for bit (``np.array_equal``) against the straightforward
formulation it replaced. Bit identity is the right tolerance here: both sides perform the same
IEEE operations on the same operands (in place instead of into temporaries, a float32 operand
promoted to float64 once instead of inside each mixed product, a + b as b + a).
"""

from __future__ import annotations

import numpy as np
import pytest

from aatest.twin import fastmath, table
from aatest.twin.daq import quantise_adc
from aatest.twin.grid import Grid
from aatest.twin.model import AxisModel, DaqModel, RateRipple

_TWO_PI = 2.0 * np.pi


def _reference_normal(rng: np.random.Generator, n: int) -> np.ndarray:
    """Box–Muller as written before: each stage into a new array."""
    half = (n + 1) // 2
    u = rng.random(2 * half)
    radius = np.sqrt(-2.0 * np.log(1.0 - u[:half]))
    s, c = fastmath.sincos32(u[half:] * _TWO_PI, np.float32)
    return np.concatenate([radius * c, radius * s])[:n]


@pytest.mark.parametrize("n", [1, 2, 7, 131_076])
def test_standard_normal_in_place_equals_the_plain_transform(n: int) -> None:
    fast = fastmath.standard_normal(np.random.default_rng(7), n)
    assert fast.shape == (n,)
    assert np.array_equal(fast, _reference_normal(np.random.default_rng(7), n))


def _reference_ripple(ripple: RateRipple, angle: np.ndarray, rate: np.ndarray,
                      accel: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The ripple as first written: every term a new array, float32 terms in mixed products."""
    k = 2 * np.pi * ripple.cycles_per_deg
    sin, cos = fastmath.sincos32(k * angle + ripple.phase_rad, np.float32)
    a = np.float32(ripple.amplitude_deg)
    if ripple.rejection_bandwidth_hz is None:
        s, c = a * sin, a * cos
    else:
        r = np.abs(rate).astype(np.float32) * np.float32(
            ripple.cycles_per_deg / ripple.rejection_bandwidth_hz)
        r2 = r * r
        r3 = r2 * r
        d_re, d_im = 1.0 - 3.0 * r2, 3.0 * r - r3
        scale = (-a) * r3 / (d_re * d_re + d_im * d_im)
        s_re, s_im = scale * d_im, scale * d_re
        s, c = sin * s_re + cos * s_im, cos * s_re - sin * s_im
    return angle + s, rate + k * rate * c, accel + k * accel * c - (k * rate) ** 2 * s


def _sine_motion(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A 7 Hz, 3° sine (rates through zero, where the rejection's r is tiny) plus noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 2000.0
    w = 2 * np.pi * 7.0
    jitter = 1e-6 * rng.standard_normal(n)
    return (3.0 * np.sin(w * t) + 40.0 + jitter, 3.0 * w * np.cos(w * t) + jitter,
            -3.0 * w * w * np.sin(w * t) + jitter)


@pytest.mark.parametrize("rejection_hz", [None, 40.0, 0.5])
def test_ripple_in_place_equals_the_plain_chain_rule(rejection_hz: float | None) -> None:
    ripple = RateRipple(cycles_per_deg=2.0, amplitude_deg=1.2e-4, phase_rad=1.0,
                        rejection_bandwidth_hz=rejection_hz)
    angle, rate, accel = _sine_motion(20_001, seed=3)
    kept = angle.copy(), rate.copy(), accel.copy()
    fast = table._add_ripple(ripple, angle, rate, accel)
    for mine, plain in zip(fast, _reference_ripple(ripple, *kept), strict=True):
        assert mine.dtype == np.float64
        assert np.array_equal(mine, plain)
    for given, before in zip((angle, rate, accel), kept, strict=True):  # inputs untouched
        assert np.array_equal(given, before)


def test_adc_in_place_equals_the_plain_formula() -> None:
    daq = DaqModel()
    lo, hi = daq.adc_range_v
    lsb = (hi - lo) / 2**daq.adc_bits
    volts = np.random.default_rng(4).uniform(1.2 * lo, 1.2 * hi, 50_001)  # both clip ends
    plain = np.clip(np.round((volts - lo) / lsb) * lsb + lo, lo, hi - lsb)
    assert np.array_equal(quantise_adc(volts, daq), plain)


@pytest.mark.parametrize(("start_s", "dt_s"), [(0.0, 5e-4), (12.345678, 1.0 / 2000.0 * (1 + 12e-6)),
                                               (-3.1, 1e-3)])
def test_grid_times_in_place_equal_the_plain_formula(start_s: float, dt_s: float) -> None:
    grid = Grid(start_s, dt_s, 140_001)
    assert np.array_equal(grid.times, start_s + dt_s * np.arange(grid.n))


def _reference_estimates(true_angle_deg: np.ndarray, model: AxisModel, dt_s: float,
                         method: str, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """``estimates`` as first written: the counts and the feedback in new arrays."""
    res = model.encoder_resolution_deg
    noisy = table._noisy(true_angle_deg, model.estimate_noise_deg, rng)
    counts = np.round(noisy / res) if res > 0.0 else noisy
    raw = table._noisy(true_angle_deg, model.encoder_noise_deg, rng)
    raw = np.round(raw / res) * res if res > 0.0 else raw
    p = table.STENCIL_PAD
    n = true_angle_deg.size - 2 * p
    f = [counts[p + k: p + k + n] for k in (-2, -1, 0, 1, 2)]
    quanta = table.estimate_quanta(model, dt_s, method)
    rate, accel = table._stencils(f, method)
    return {"position_deg": f[2] * quanta["position_deg"], "rate_dps": rate * quanta["rate_dps"],
            "accel_dps2": accel * quanta["accel_dps2"], "feedback_deg": raw[p: p + n]}


@pytest.mark.parametrize("method", ["five_point", "central"])
@pytest.mark.parametrize(("resolution_deg", "noise_deg"), [(1e-5, 3e-6), (0.0, 3e-6), (1e-5, 0.0)])
def test_estimates_in_place_equal_the_plain_ones(method: str, resolution_deg: float,
                                                 noise_deg: float) -> None:
    model = AxisModel(encoder_resolution_deg=resolution_deg, estimate_noise_deg=noise_deg,
                      encoder_noise_deg=noise_deg)
    angle, _, _ = _sine_motion(10_004, seed=8)
    kept = angle.copy()
    fast = table.estimates(angle, model, 1e-3, method, np.random.default_rng(2))
    plain = _reference_estimates(kept, model, 1e-3, method, np.random.default_rng(2))
    assert fast.keys() == plain.keys()
    for name, values in fast.items():
        assert np.array_equal(values, plain[name]), name
    assert np.array_equal(angle, kept)  # the true angle is not written to


def test_equal_grids_share_one_read_only_times_array() -> None:
    """The stages of a step build the DAQ grid as separate Grid objects: one array for all."""
    first, again = Grid(123.456, 1.0 / 2000.0, 50_000), Grid(123.456, 1.0 / 2000.0, 50_000)
    assert again.times is first.times
    assert not first.times.flags.writeable
    assert np.array_equal(first.times, 123.456 + (1.0 / 2000.0) * np.arange(50_000))
    # grids that differ only in a zero's sign or in a last bit keep their own arrays
    assert Grid(-0.0, 1.0, 5000).times is not Grid(0.0, 1.0, 5000).times
    assert Grid(1.0, 1.0, 1).times is not Grid(1.0, 1.0, 1).times  # too short to keep
    assert Grid(np.nextafter(123.456, 200.0), 1.0 / 2000.0, 50_000).times is not first.times


def test_settled_temperature_equals_the_decay_formula() -> None:
    """At the set-point the temperature is the set-point + 0·decay at every time, bit for bit
    (before the step time too, and for a negative set-point)."""
    from aatest.twin.chamber import ThermalState
    from aatest.twin.model import ChamberModel

    for setpoint_c in (23.0, -40.0, 0.0):
        state = ThermalState(ChamberModel(), setpoint_c=setpoint_c, from_c=setpoint_c,
                             step_time_s=100.0)
        times = np.linspace(-50.0, 9e4, 100_001)
        decay = np.exp(-np.maximum(times - 100.0, 0.0) / state.model.sensor_time_constant_s)
        plain = setpoint_c + (setpoint_c - setpoint_c) * decay
        got = state.temperature_at(times)
        assert np.array_equal(got, plain)
        assert np.array_equal(np.signbit(got), np.signbit(plain))
    moving = ThermalState(ChamberModel(), setpoint_c=60.0, from_c=23.0, step_time_s=100.0)
    times = np.linspace(0.0, 9e4, 1001)
    tau = moving.model.sensor_time_constant_s
    assert np.array_equal(moving.temperature_at(times),
                          60.0 + (23.0 - 60.0) * np.exp(-np.maximum(times - 100.0, 0.0) / tau))
