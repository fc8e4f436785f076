"""Acceleration references: amplitude, phase and noise against the synthetic truth."""

from __future__ import annotations

import time

import numpy as np
import pytest
from synthetic_rig import SynthRig, make_step, sine_step

from aatest.clocksync import SyncedStep, synchronise
from aatest.plugins.analysis._common import fundamental
from aatest.plugins.analysis.reference import METHODS, levant_differentiator, reference_accel


@pytest.fixture(scope="module")
def synced():  # type: ignore[no-untyped-def]
    return synchronise(make_step(sine_step("s", 40, 200.0, samples=16384), SynthRig(), seed=7))


@pytest.mark.parametrize("method", METHODS)
def test_reference_fundamental_and_noise(synced: SyncedStep, method: str) -> None:
    fs, f0 = synced.sample_rate_hz, synced.step.frequency_hz
    ref = reference_accel(synced, method)
    amp = abs(fundamental(ref, f0, fs))
    assert amp == pytest.approx(200.0, rel=0.01)
    truth = -synced.step.amplitude_deg * (2 * np.pi * f0) ** 2 * np.sin(
        2 * np.pi * f0 * np.arange(len(synced)) / fs
        + np.angle(fundamental(synced.table["inner_position_deg"], f0, fs)) + np.pi / 2)
    err = (ref - truth)[200:-200]
    # raw stencils amplify the 0.2″ position noise (≈550 °/s² RMS for the central one);
    # Levant chatters on the noisy rate estimate (≈300 °/s²), the smoothers stay ≈1 °/s²
    limit = {"table": 600.0, "central_position": 600.0, "five_point_position": 800.0,
             "central_rate": 200.0, "five_point_rate": 250.0, "levant": 400.0}.get(method, 25.0)
    rms = float(np.sqrt(np.mean(err**2)))
    print(f"reference {method}: RMS error vs truth {rms:.2f} °/s²")
    assert rms < limit


def test_levant_speed_and_accuracy() -> None:
    fs = 2000.0
    t = np.arange(2**17) / fs
    rate = 50.0 * np.sin(2 * np.pi * t)
    t0 = time.perf_counter()
    acc = levant_differentiator(rate, fs, lipschitz_dps3=2 * 50.0 * (2 * np.pi) ** 2)
    elapsed = time.perf_counter() - t0
    truth = 50.0 * 2 * np.pi * np.cos(2 * np.pi * t)
    assert np.sqrt(np.mean((acc - truth)[2000:] ** 2)) < 0.02 * 50.0 * 2 * np.pi
    assert elapsed < 1.0, f"Levant took {elapsed:.2f} s per 2^17 samples"
