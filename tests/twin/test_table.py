"""Table and controller behaviour of docs/method.md §1.2, measured on twin output."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from twin_steps import aligned_daq, fundamental, rate_step, sine_step, static_step

from aatest.engine.errors import EnvelopeRefused
from aatest.plugins.sensors.sr207 import SR207Unit
from aatest.twin.api import nominal_rig_model, realistic_rig_model, simulate_step
from aatest.twin.grid import Grid
from aatest.twin.profiles import AxisProfile
from aatest.twin.table import _stencils, tracked

#: the three-sensor unit (S_Z on I, S_Y on O, S_X on P)
AAMU = SR207Unit().datasheet()

FS = 2000.0


def _amplitude_spectrum(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    x = np.asarray(x) - np.mean(x)
    return np.fft.rfftfreq(x.size, 1 / FS), 2 * np.abs(np.fft.rfft(x)) / x.size


def test_motor_on_standstill_shows_the_30_40_hz_band() -> None:
    sim = simulate_step(realistic_rig_model(), static_step(samples=16384), seed=31)
    freq, amp = _amplitude_spectrum(sim.table["inner_accel_dps2"])
    low = (freq > 1) & (freq < 200)
    peak_hz = freq[low][np.argmax(amp[low])]
    assert 30.0 <= peak_hz <= 40.0
    band = (freq >= 30) & (freq <= 40)
    outside = low & ~band
    # the band stands far above the estimator's white noise floor
    assert amp[band].max() > 20 * np.median(amp[outside])
    # the sensor sees the same vibration (it is real motion, not log noise)
    f2, a2 = _amplitude_spectrum(sim.daq["v_sz"])
    assert 30.0 <= f2[(f2 > 1) & (f2 < 200)][np.argmax(a2[(f2 > 1) & (f2 < 200)])] <= 40.0


def test_motor_off_no_band_and_slow_drift() -> None:
    step = static_step(samples=16384, motor_on=False)
    sim = simulate_step(realistic_rig_model(), step, seed=32)
    freq, amp = _amplitude_spectrum(sim.table["inner_accel_dps2"])
    band = (freq >= 30) & (freq <= 40)
    assert amp[band].max() < 3 * np.median(amp[(freq > 1) & (freq < 200)])
    pos = np.asarray(sim.table["inner_position_deg"])
    slope = np.polyfit(sim.table.time_s, pos, 1)[0]
    assert_allclose(abs(slope), 0.002, rtol=0.05)  # drifts slowly away from zero


@pytest.mark.parametrize(
    ("rate_dps", "lines_hz"), [(30.0, (30.0, 60.0)), (50.0, (50.0, 100.0))], ids=["30dps", "50dps"]
)
def test_constant_rate_ripple_peaks_scale_with_rate(rate_dps: float, lines_hz: tuple) -> None:
    sim = simulate_step(realistic_rig_model(), rate_step(rate_dps, samples=16000), seed=33)
    pos = np.asarray(sim.table["inner_position_deg"])
    detrended = pos - np.polyval(np.polyfit(sim.table.time_s, pos, 1), sim.table.time_s)
    freq, amp = _amplitude_spectrum(detrended)
    window = (freq > 5) & (freq < 150) & ((freq < 29) | (freq > 41))  # outside the motor band
    floor = np.median(amp[window])
    for line in lines_hz:
        assert amp[np.argmin(np.abs(freq - line))] > 20 * floor, line


def test_10_dps_shows_a_single_ripple_peak_at_20_hz() -> None:
    # 32 s: the 0.1″ ripple's rejected 10 Hz line (≈0.0014″) stands above the estimator noise
    sim = simulate_step(realistic_rig_model(), rate_step(10.0, samples=64000), seed=34)
    pos = np.asarray(sim.table["inner_position_deg"])
    detrended = pos - np.polyval(np.polyfit(sim.table.time_s, pos, 1), sim.table.time_s)
    freq, amp = _amplitude_spectrum(detrended)
    a10, a20 = (amp[np.argmin(np.abs(freq - f))] for f in (10.0, 20.0))
    assert a20 > 5 * a10  # the servo rejects the 1 cycle/° error at 10 Hz
    window = (freq > 5) & (freq < 29)
    assert freq[window][np.argmax(amp[window])] == pytest.approx(20.0, abs=0.2)


def test_estimates_are_differences_of_the_position_estimate() -> None:
    sim = simulate_step(realistic_rig_model(), sine_step(1.0, 100.0), seed=35)
    p = np.asarray(sim.table["inner_position_deg"])
    rate = np.asarray(sim.table["inner_rate_dps"])
    accel = np.asarray(sim.table["inner_accel_dps2"])
    h = 1 / FS
    assert_allclose(rate[1:-1], (p[2:] - p[:-2]) / (2 * h), rtol=0, atol=1e-9)
    assert_allclose(accel[1:-1], (p[2:] - 2 * p[1:-1] + p[:-2]) / h**2, rtol=0, atol=1e-5)
    # the raw feedback is a different, noisier measurement of the same motion
    raw = np.asarray(sim.table["inner_feedback_deg"])
    assert 0 < np.std(raw - sim.truth["inner_angle_deg"]) < 1e-3


def test_acceleration_estimate_is_noisy_rate_estimate_clean() -> None:
    step = sine_step(1.0, 400.0)
    sim = simulate_step(realistic_rig_model(), step, seed=36)
    accel_err = np.asarray(sim.table["inner_accel_dps2"]) - sim.truth["inner_accel_dps2"]
    rate_err = np.asarray(sim.table["inner_rate_dps"]) - sim.truth["inner_rate_dps"]
    # √6·σ/h² with σ = 0.01″: ≈ 27 °/s² — the ≈30 °/s² RMSE of docs/method.md §4.3
    assert 20.0 < np.std(accel_err) < 40.0
    assert np.std(rate_err) < 0.01
    # relative to the signal: acceleration ≈ 7 % noise, rate ≈ 7e-5 (≈ 1000× cleaner)
    assert np.std(accel_err) / 400 > 300 * np.std(rate_err) / np.max(
        np.abs(sim.truth["inner_rate_dps"])
    )


def test_tracking_loop_follows_sines_with_small_error() -> None:
    prof = AxisProfile(amplitude_deg=1.0, frequency_hz=10.0)
    real = tracked(prof, 40.0)
    assert_allclose(real.amplitude_deg, 1.0, atol=0.02)
    assert abs(real.phase_rad) < np.radians(1.5)
    assert tracked(AxisProfile(rate_dps=30.0), 40.0) == AxisProfile(rate_dps=30.0)


def test_controller_refuses_beyond_limits() -> None:
    with pytest.raises(EnvelopeRefused, match="rate"):
        AxisProfile(rate_dps=1300.0).check("inner", 1200.0, 1000.0)
    with pytest.raises(EnvelopeRefused, match="acceleration"):
        AxisProfile(amplitude_deg=1.0, frequency_hz=3.0).check("outer", 500.0, 200.0)
    AxisProfile(amplitude_deg=1.0, frequency_hz=2.0).check("outer", 500.0, 200.0)  # 158 °/s²


def test_outer_unbalance_leaks_into_the_perpendicular_axis() -> None:
    base = realistic_rig_model(AAMU)
    perfect_mount = base.unit.model_copy(
        update={"sensor_remount_sigma_deg": 0.0, "block_remount_sigma_deg": 0.0}
    )
    base = base.model_copy(update={"unit": perfect_mount})
    model = base.model_copy(
        update={"table": base.table.model_copy(update={"unbalance_parasitic_dps2_per_dps2": 0.02})}
    )
    step = sine_step(1.0, 100.0, axis="outer")
    sim = simulate_step(model, step, seed=37)
    x = fundamental(aligned_daq(sim, "v_sx"), step.cycles)
    o = fundamental(aligned_daq(sim, "v_sy"), step.cycles)
    assert_allclose(abs(x) / abs(o), 0.02, atol=0.005)  # misalignments add < 0.5 %
    # the controller's correction rings: the leak is resonant in the 30–40 Hz band
    balanced = base.model_copy(
        update={"table": base.table.model_copy(update={"unbalance_parasitic_dps2_per_dps2": 0.0})}
    )
    still = simulate_step(balanced, step, seed=37)
    freq = np.fft.rfftfreq(len(sim.table), 1 / 2000.0)
    band = (freq > 30) & (freq < 40)

    def band_rms(s: object) -> float:  # true acceleration along S_X's axis, 30–40 Hz
        alpha = np.asarray(s.truth["alpha_v_sx"])[: len(sim.table)]
        return float(np.sqrt(np.sum(np.abs(np.fft.rfft(alpha))[band] ** 2)))

    assert band_rms(sim) > 3 * band_rms(still)


def test_phasor_grid_matches_direct_evaluation() -> None:
    grid = Grid(1234.5, 1 / FS, 5000)
    z = grid.phasor(2 * np.pi * 7.3, 0.4)
    assert_allclose(z, np.exp(1j * (2 * np.pi * 7.3 * grid.times + 0.4)), atol=1e-9)


def test_nominal_table_is_ideal() -> None:
    sim = simulate_step(nominal_rig_model(), sine_step(2.0, 100.0), seed=38)
    # only the central difference's truncation error (ωh)²/12 ≈ 3e-6 remains
    assert_allclose(sim.table["inner_accel_dps2"], sim.truth["inner_accel_dps2"], rtol=0, atol=4e-4)


@pytest.mark.parametrize("method", ["five_point", "central"])
def test_in_place_stencils_are_the_written_formulas(method: str) -> None:
    # exact: the in-place evaluation runs the same float64 operations in the same order
    # (x − y is x + (−y), a + b is b + a bit for bit), on non-integer "counts" too (an ideal
    # encoder's estimates are the angles themselves)
    counts = np.random.default_rng(4).normal(33.3, 123.456, 4000)
    n = counts.size - 4
    f = [counts[2 + k: 2 + k + n] for k in (-2, -1, 0, 1, 2)]
    rate, accel = _stencils(f, method)
    if method == "five_point":
        assert np.array_equal(rate, -f[4] + 8 * f[3] - 8 * f[1] + f[0])
        assert np.array_equal(accel, -f[4] + 16 * f[3] - 30 * f[2] + 16 * f[1] - f[0])
    else:
        assert np.array_equal(rate, f[3] - f[1])
        assert np.array_equal(accel, f[3] - 2 * f[2] + f[1])
