"""Sensor, unit and kinematics behaviour of docs/method.md §1.3, §3, §4 measured on twin output."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from twin_steps import aligned_daq, fundamental, sine_step, static_step

from aatest.engine.steps import Mounting, PlannedStep
from aatest.plugins.sensors.sr207 import SR207Unit
from aatest.twin import kinematics as kin
from aatest.twin.api import World, realistic_rig_model, run_step, simulate_step
from aatest.twin.sensor import play_operator

#: the three-sensor unit (S_Z on I, S_Y on O, S_X on P)
AAMU = SR207Unit().datasheet()

K = 0.004014


def _frf(model, f_hz: float, accel: float, seed: int) -> complex:
    step = sine_step(f_hz, accel, samples=32768)
    sim = simulate_step(model, step, seed)
    return fundamental(aligned_daq(sim, "v_sz"), step.cycles) / fundamental(
        sim.truth["accel_dps2"], step.cycles), step.frequency_hz


def test_stepped_sine_frf_matches_measured_behaviour() -> None:
    """≈ −48 dB flat to 4 Hz, 0.2–1 dB down at 10 Hz, phase delay 12–15 ms (24–31 samples)."""
    model = realistic_rig_model(drift_ppm=0.0)
    points = {f: _frf(model, f, 100.0, 40 + i) for i, f in enumerate((0.4, 1.0, 4.0, 10.0))}
    gain_db = {f: 20 * np.log10(abs(h)) for f, (h, _) in points.items()}
    assert_allclose(gain_db[0.4], 20 * np.log10(K), atol=0.1)  # −47.9 dB
    assert gain_db[0.4] - gain_db[4.0] < 0.15
    assert 0.2 <= gain_db[0.4] - gain_db[10.0] <= 1.0
    for f, (h, f_exact) in points.items():
        delay_s = -np.angle(h) / (2 * np.pi * f_exact)
        assert 0.012 <= delay_s <= 0.015, (f, delay_s)


def test_output_noise_is_about_one_millivolt_and_slip_ring_adds_11() -> None:
    step = static_step(samples=16384, motor_on=False)
    v = np.asarray(simulate_step(realistic_rig_model(), step, 45).daq["v_sz"])
    assert_allclose(np.std(v), 0.001, rtol=0.1)
    v_ring = np.asarray(simulate_step(realistic_rig_model(slip_ring=True), step, 45).daq["v_sz"])
    assert 0.0105 < np.sqrt(np.var(v_ring) - np.var(v)) < 0.0115


def test_g_sensitivity_flips_sign_between_input_axis_up_and_down() -> None:
    model = realistic_rig_model()
    means = {}
    for outer in (0.0, 90.0, 180.0):
        sim = simulate_step(model, static_step(samples=16384, outer_deg=outer, motor_on=False), 46)
        means[outer] = np.mean(sim.daq["v_sz"])
    up, _level, down = ((means[o] - means[90.0]) / K for o in (0.0, 90.0, 180.0))
    assert_allclose(up, 0.573, atol=0.02) and assert_allclose(down, -0.573, atol=0.02)
    assert up > 0 > down


def test_coordinated_two_axis_rates_give_omega_i_times_omega_o() -> None:
    """Inner 360 °/s, outer 20 °/s: S_Y sees α = −ω_i·ω_o·sin(ω_i t), 2π·20 = 125.7 °/s² at 1 Hz."""
    step = PlannedStep(id="coord", kind="constant_rate", axis="both", duration_s=8.0,
                       settle_s=1.0, samples=16000, rate_dps=360.0, outer_rate_dps=20.0)
    sim = simulate_step(realistic_rig_model(AAMU, drift_ppm=0.0), step, 47)
    expected = np.radians(360.0) * 20.0
    amp_y = abs(fundamental(aligned_daq(sim, "v_sy"), 8)) / K
    assert_allclose(amp_y, expected, rtol=0.01)
    # the sensor on the inner axis does not see it (only its < 1 % cross-axis/misalignment)
    assert abs(fundamental(aligned_daq(sim, "v_sz"), 8)) / K < 0.01 * expected


@pytest.mark.pinned
def test_kinematics_frames_follow_the_contract() -> None:
    """Outer motion seen by a sensor on I at inner ψ is along (sin ψ, cos ψ, 0)."""
    for psi in (0.0, 90.0, 33.0):
        sc = (np.sin(np.radians(psi)), np.cos(np.radians(psi)))
        alpha = kin.angular_acceleration_top(sc, 0.0, 0.0, 0.0, 1.0)
        assert_allclose(alpha, [sc[0], sc[1], 0.0], atol=1e-15)
    for outer, up in ((0.0, 1.0), (180.0, -1.0), (90.0, 0.0)):
        so = (np.sin(np.radians(outer)), np.cos(np.radians(outer)))
        assert_allclose(kin.gravity_top((0.0, 1.0), so)[2], up, atol=1e-15)
    # orthogonality error ε: the inner-axis sensor picks up −sin ε of outer acceleration
    eps = kin.GimbalErrors(orthogonality_arcsec=3.0)
    assert_allclose(kin.angular_acceleration_top((0.0, 1.0), 0.0, 0.0, 0.0, 100.0, eps)[2],
                    -100 * np.sin(3 * kin.ARCSEC_RAD), rtol=1e-12)
    for frame in kin.SEAT_FRAMES.values():
        assert_allclose(np.cross(frame[:, 0], frame[:, 1]), frame[:, 2])


@pytest.mark.pinned
@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-50, 50), min_size=1, max_size=300), st.floats(0.0, 5.0))
def test_vectorised_play_operator_equals_its_recursive_definition(xs: list, r: float) -> None:
    x = np.asarray(xs)
    y_ref = np.empty_like(x)
    prev = x[0]
    for k, xk in enumerate(x):
        prev = min(xk + r, max(xk - r, prev))
        y_ref[k] = prev
    assert_allclose(play_operator(x, r), y_ref, rtol=0, atol=1e-12)


def test_remount_scatter_has_the_stated_spread() -> None:
    """Block re-mounts tilt the unit with σ per axis; the z tilt is Rayleigh, mean σ·√(π/2)."""
    model = realistic_rig_model(AAMU)
    world = World(model, seed=48)
    tilts = []
    for i in range(300):
        step = PlannedStep(id=f"r{i}", kind="static", mounting=Mounting(remount="block"))
        world.apply_mounting(step)
        tilts.append(np.degrees(np.arccos(np.clip(world.block_error[2, 2], -1, 1))))
    sigma = model.unit.block_remount_sigma_deg
    assert_allclose(np.mean(tilts), sigma * np.sqrt(np.pi / 2), rtol=0.1)


def test_pivot_flips_the_equivalent_misalignment() -> None:
    """Experiment 2 (excite O), original vs pivoted: S_Z's cross response changes sign."""
    real = realistic_rig_model(AAMU, drift_ppm=0.0)
    # noise (≈1.4e-4 of 100 °/s² per bin after the 100 Hz filter), hysteresis, the resolution
    # threshold and leakage of the incoherent 35 Hz motor band make a 0.03 °/s² cross response
    # irregular at the 1e-4 level (as measured at very low acceleration): switch them off to
    # check the geometry exactly; a perfect mounting isolates the sensor's own terms
    quiet_sensor = {"hysteresis": None, "resolution_dps2": 0.0, "noise_rms_v": 0.0}
    sensors = [s.model_copy(update=quiet_sensor) for s in real.sensors]
    quiet = {ax: getattr(real.table, ax).model_copy(update={"motor_vibration": None})
             for ax in ("inner", "outer")}
    perfect_mount = real.unit.model_copy(update={"sensor_remount_sigma_deg": 0.0,
                                                 "block_remount_sigma_deg": 0.0})
    # without noise to dither it, the logger's 305 µV step (16 bit over ±10 V) would swallow the
    # 1.2e-4 V cross response: a 32-bit converter checks the geometry, not the quantiser
    fine_adc = real.daq.model_copy(update={"adc_bits": 32})
    model = real.model_copy(update={"sensors": sensors, "unit": perfect_mount, "daq": fine_adc,
                                    "table": real.table.model_copy(update=quiet)})
    world = World(model, seed=49)
    base = sine_step(1.0, 100.0, samples=8192, axis="outer")
    resp = []
    for pivoted in (False, True):
        step = base.model_copy(update={"id": f"p{pivoted}", "mounting": Mounting(pivoted=pivoted)})
        sim = run_step(world, step)
        resp.append(fundamental(aligned_daq(sim, "v_sz"), step.cycles)
                    / fundamental(sim.truth["outer_accel_dps2"], step.cycles) / K)
    # S_Z's own y lies along O: internal misalignment (0.2° towards azimuth 30°) plus the
    # cross-axis ratio_y (−0.002), plus the unbalance leak (k about P) seen through the x
    # terms (misalignment + ratio_x 0.003); all turn over with the sensor, so the sum flips
    tilt = np.sin(np.radians(0.2))
    expected = (tilt * np.sin(np.radians(30.0)) - 0.002
                + model.table.unbalance_parasitic_dps2_per_dps2
                * (tilt * np.cos(np.radians(30.0)) + 0.003))
    assert_allclose([resp[0].real, resp[1].real], [expected, -expected], atol=2e-5)


def test_chamber_temperature_drives_the_bias_with_thermal_lag() -> None:
    model = realistic_rig_model()
    world = World(model, seed=50)
    world.motor_on = True
    world.set_temperature(-21.0)
    world.lab_time_s += model.chamber.sensor_time_constant_s  # one τ later, not yet stable
    sim = run_step(world, static_step(samples=4096, motor_on=False))
    temp = np.mean(sim.daq["temperature_c"])
    expected = -21.0 + (22.0 + 21.0) * np.exp(-1.0)
    assert_allclose(temp, expected, atol=0.5)
    bias_shift = np.mean(sim.daq["v_sz"]) - model.sensors[0].bias_v
    g_term_v = 0.573 * K  # input axis up: +1 g
    assert_allclose(bias_shift, -0.0003 * (temp - 25.0) + g_term_v, atol=2e-4)
    assert bias_shift > 0  # higher bias when cold (docs/method.md §1.3)


@pytest.mark.slow
def test_full_length_step_on_three_channels() -> None:
    step = sine_step(1.0, 400.0, samples=2**17)
    sim = simulate_step(realistic_rig_model(AAMU), step, 51)
    assert len(sim.table) == 2**17 and sim.daq.sensor_channels() == ["v_sz", "v_sy", "v_sx"]


def test_first_mounting_is_a_draw_and_the_nominal_mounting_is_perfect() -> None:
    from aatest.twin.api import nominal_rig_model
    from aatest.twin.model import RigModel

    real = World(realistic_rig_model(AAMU), seed=52)
    tilt_deg = np.degrees(np.arccos(real.block_error[2, 2]))
    assert 0.0 < tilt_deg < 5 * real.model.unit.block_remount_sigma_deg
    assert_allclose(World(nominal_rig_model(), seed=52).block_error, np.eye(3))
    assert_allclose(World(RigModel(), seed=52).block_error, np.eye(3))  # minimal default


def test_horizontal_sensors_pick_up_more_building_vibration() -> None:
    """Outer 0°: S_Z vertical, S_Y and S_X horizontal; the floor rocks about horizontal axes."""
    model = realistic_rig_model(AAMU)
    sim = simulate_step(model, static_step(samples=16384, motor_on=False), 53)
    rms = {ch: np.std(sim.daq[ch]) for ch in ("v_sz", "v_sy", "v_sx")}
    # 0.3 °/s² RMS of 5–30 Hz rocking, partly attenuated by the sensor's 30 Hz dynamics
    for ch in ("v_sy", "v_sx"):
        rocking_dps2 = np.sqrt(rms[ch] ** 2 - 0.001**2) / K
        assert 0.15 < rocking_dps2 <= 0.3, ch
    assert rms["v_sz"] < 0.85 * min(rms["v_sy"], rms["v_sx"])
    assert_allclose(rms["v_sz"], 0.001, rtol=0.1)
