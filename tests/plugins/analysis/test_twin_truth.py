"""Analyses against the digital twin with known truth (issue 4 "Done when" tolerances)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from analyse import analyse
from scipy import signal
from synthetic_rig import sine_step, static_step
from twin_helpers import twin_dataset

from aatest.engine.analysis.passes import run_analyses, run_analysis

FS = 2000.0


@pytest.fixture(scope="module")
def cal_run(realistic_unit):  # type: ignore[no-untyped-def]
    steps = [sine_step("cal", 16, 400.0, samples=32768, settle_s=2.0),
             sine_step("f5", 41, 100.0, samples=16384, settle_s=2.0),
             sine_step("f10", 82, 100.0, samples=16384, settle_s=2.0)]
    data, truths = twin_dataset(realistic_unit, steps)
    done = run_analyses(data, ["sync", "scale_factor", "frf"])
    results = {key: result.model_dump() for key, result in done.values.items()}
    return realistic_unit, data, truths, results


def test_sync_against_twin_clock(cal_run) -> None:  # type: ignore[no-untyped-def]
    _, _, truths, results = cal_run
    for step, truth in zip(results["sync"]["steps"], truths, strict=True):
        assert abs(step["drift_ppm"] - truth["drift_ppm"]) < 1.0
        assert step["residual_rms_us"] < 10.0
        assert abs(step["offset_s"] - truth["offset_s"]) < 0.25e-3


def test_scale_factor_against_twin(cal_run) -> None:  # type: ignore[no-untyped-def]
    model, _, truths, results = cal_run
    s = model.sensor("v_sz")
    temp = truths[0]["temperature_c"]
    truth = s.scale_v_per_dps2 * (1 + s.scale_temperature.coefficient_per_c * (temp - 25.0))
    v = results["scale_factor"]["v_sz"]
    assert v["scale_v_per_dps2"] == pytest.approx(truth, rel=1e-3)
    assert set(results["scale_factor"]) == {"v_sz"}  # only the I sensor is excited
    # the twin's cubic (c3 = 0.002, ≈0.005 % FR) sits at the resolution threshold of the order
    # choice: on this short record order 1 or 3 are both "not meaningfully worse"; the rotor's
    # jerk distortion (c·j² = −c·ω²·α² + const at one frequency, 0.17 °/s² at 1 Hz, 400 °/s²)
    # is a quadratic term of the same size, so order 2 is as true
    assert v["order"] in (1, 2, 3)


def _truth_response(model: Any, f_hz: float, accel_dps2: float) -> complex:
    """K·H_sensor·H_antialias·e^{−jωτ} of the twin's v_sz chain at a sine of peak
    ``accel_dps2`` (the amplitude sets the damping when ``amplitude_damping`` is on)."""
    from aatest.twin.daq import antialias_filter
    from aatest.twin.sensor import damping_of, dynamics_filter

    s = model.sensor("v_sz")
    zeta = s.sensor_dynamics.damping
    if s.amplitude_damping is not None:
        zeta = float(damping_of(s.amplitude_damping, zeta, np.array([accel_dps2]))[0])
    b, a = dynamics_filter(s.sensor_dynamics.natural_frequency_hz, zeta, 1 / FS)
    b2, a2, _ = antialias_filter(float(model.daq.antialias_hz), 1 / FS)
    h = (signal.freqz(b, a, worN=[f_hz], fs=FS)[1][0]
         * signal.freqz(b2, a2, worN=[f_hz], fs=FS)[1][0])
    return complex(s.scale_v_per_dps2 * h * np.exp(-2j * np.pi * f_hz * s.time_delay.delay_s))


def test_frf_delay_against_twin(cal_run) -> None:  # type: ignore[no-untyped-def]
    model, _, _, results = cal_run
    for p in results["frf"]["v_sz"]:
        h = _truth_response(model, p["frequency_hz"], p["accel_dps2"])
        truth_delay = -np.angle(h) / (2 * np.pi * p["frequency_hz"])
        assert p["delay_s"] == pytest.approx(truth_delay, abs=0.25e-3)
        assert p["gain_db"] == pytest.approx(20 * np.log10(abs(h)), abs=0.05)


def test_bias_against_twin(realistic_unit) -> None:  # type: ignore[no-untyped-def]
    positions = [(0, 0), (0, 180), (0, 90), (90, 90), (180, 90), (270, 90)]
    steps = [static_step(f"r{r}-{i}-{o}", i, o, samples=4096, repetition=r, settle_s=1.0)
             for r in (1, 2) for i, o in positions]
    data, truths = twin_dataset(realistic_unit, steps)
    values = analyse("bias", data)
    temp = float(np.mean([t["temperature_c"] for t in truths]))
    for s in realistic_unit.sensors:
        truth_bias = s.bias_v + s.bias_temperature.coefficient_v_per_c * (temp - 25.0)
        assert values[s.channel]["bias_v"] == pytest.approx(truth_bias, abs=1e-4)
        g_truth = s.g_sensitivity.coefficient_dps2_per_g
        assert values[s.channel]["g_sensitivity_dps2_per_g"] == pytest.approx(g_truth, rel=0.1)


@pytest.fixture(scope="module")
def tf_run():  # type: ignore[no-untyped-def]
    from test_tfest import F28

    from aatest.twin.api import realistic_rig_model
    from aatest.twin.model import SensorDynamics, SensorModel, TimeDelay

    sensor = SensorModel(sensor_dynamics=SensorDynamics(natural_frequency_hz=30.0, damping=0.9),
                         time_delay=TimeDelay(delay_s=0.0015))
    model = realistic_rig_model([sensor])
    n = 16384
    steps = [sine_step(f"c{c}", c, 100.0, samples=n, settle_s=1.0)
             for c in sorted({round(f * n / FS) for f in F28})]
    data, _ = twin_dataset(model, steps)
    return model, run_analysis("transfer_function", data, {"antialias_hz": model.daq.antialias_hz})


def test_transfer_function_against_twin(tf_run) -> None:  # type: ignore[no-untyped-def]
    _model, out = tf_run
    v = out.result.model_dump()["v_sz"]
    assert {"poles", "zeros", "delay_s", "fit_pct", "nAIC", "FPE", "num", "den", "dt"} <= set(v)
    assert v["fit_pct"] > 95.0 and v["zeros_outside_unit_circle"] == 0
    phys = v["second_order_delay"]
    assert phys["natural_frequency_hz"] == pytest.approx(30.0, rel=0.05)
    assert phys["damping"] == pytest.approx(0.9, rel=0.05)
    assert phys["delay_s"] == pytest.approx(0.0015, abs=0.25e-3)
    assert any(k.startswith("tf_v_sz") for k in out.figures)


def test_references_against_twin_truth(cal_run) -> None:  # type: ignore[no-untyped-def]
    """Each reference against the twin's true acceleration: broadband, and in the 20 Hz band
    the calibration uses (the true motion also carries ≈125 Hz servo vibration that no
    smoothing reference keeps, and the sensor barely sees)."""
    from aatest.clocksync import synchronise_all
    from aatest.plugins.analysis.reference import METHODS, reference_accel, zero_phase_lowpass

    _, data, truths, _ = cal_run
    synced = synchronise_all(data)[0]
    truth = np.asarray(truths[0]["inner_accel_dps2"])[: len(synced)]
    broad, inband = {}, {}
    for method in METHODS:
        err = reference_accel(synced, method) - truth
        broad[method] = float(np.sqrt(np.mean(err[200:-200] ** 2)))
        inband[method] = float(np.sqrt(np.mean(zero_phase_lowpass(err, FS, 20.0)[400:-400] ** 2)))
    print("reference RMS error vs twin truth, broadband / 0–20 Hz (°/s²):",
          ", ".join(f"{k} {broad[k]:.2f}/{inband[k]:.3f}" for k in METHODS))
    assert inband["smooth"] < 1.0 and inband["savgol"] < 1.0 and inband["central_rate"] < 1.0
    assert broad["central_rate"] < broad["table"]
