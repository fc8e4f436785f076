"""Each scale-factor reference is the method it names (docs/method.md §1.2, §4.3).

On one synthetic record whose controller forms its rate and acceleration estimates as central
differences of a position estimate carrying white noise σ (0.2″), every linear reference is a
zero-phase filter G(f) of that noise, so the RMS difference of two references is predicted by
σ·√(mean over f of |G_a(f) − G_b(f)|²): the table's estimate (central second difference),
``central``/``five_point`` (first difference of the rate estimate), ``smoothed`` (second
difference through a zero-phase low-pass at its own 25 Hz corner). Sliding mode is non-linear:
it must differ from every other one and keep the fundamental.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy import signal
from synthetic_rig import SynthRig, make_step, sine_step

from aatest.clocksync import SyncedStep, synchronise
from aatest.plugins.analysis._common import fundamental
from aatest.plugins.analysis.reference import (
    PUBLIC_METHODS,
    SMOOTHED_CORNER_HZ,
    reference_accel,
    savgol_accel,
)

LINEAR = ("table_estimate", "central", "five_point", "smoothed")


@pytest.fixture(scope="module")
def synced() -> SyncedStep:
    return synchronise(make_step(sine_step("s", 40, 200.0, samples=32768), SynthRig(), seed=3))


def _response(name: str, f_hz: np.ndarray, fs: float) -> np.ndarray:
    """Zero-phase response (°/s² per ° of position) of a linear reference at f."""
    w = 2 * np.pi * f_hz / fs
    second = (2 * np.cos(w) - 2) * fs**2            # central second difference
    rate = 1j * np.sin(w) * fs                      # the controller's central rate
    if name == "table_estimate":
        return second
    if name == "central":
        return rate * 1j * np.sin(w) * fs
    if name == "five_point":
        return rate * 1j * (8 * np.sin(w) - np.sin(2 * w)) / 6 * fs
    sos = signal.butter(4, SMOOTHED_CORNER_HZ, fs=fs, output="sos")
    _, h = signal.sosfreqz(sos, worN=f_hz, fs=fs)
    return second * np.abs(h) ** 2


def _refs(synced: SyncedStep) -> dict[str, np.ndarray]:
    return {name: reference_accel(synced, PUBLIC_METHODS[name])[400:-400]  # type: ignore[index]
            for name in (*LINEAR, "sliding_mode")}


@pytest.mark.parametrize("a, b", list(itertools.combinations(LINEAR, 2)))
def test_linear_references_differ_by_their_definitions(synced: SyncedStep, a: str,
                                                       b: str) -> None:
    fs = synced.sample_rate_hz
    sigma = SynthRig().position_noise_deg
    f = np.linspace(0.0, fs / 2, 20001)
    predicted = sigma * np.sqrt(np.mean(np.abs(_response(a, f, fs) - _response(b, f, fs)) ** 2))
    refs = _refs(synced)
    measured = float(np.sqrt(np.mean((refs[a] - refs[b]) ** 2)))
    # RMS of ≈32 000 samples of filtered white noise: its relative scatter is ≈1/√(2·N_eff),
    # ≤ 4 % for the narrowest difference (smoothed vs central, N_eff ≈ N·5 %); 10 % leaves room
    assert measured == pytest.approx(predicted, rel=0.10), (a, b, measured, predicted)
    assert predicted > 1.0  # and the definitions do differ (°/s² RMS, not rounding)


def test_sliding_mode_differs_from_the_others_and_keeps_the_fundamental(
        synced: SyncedStep) -> None:
    fs, f0 = synced.sample_rate_hz, float(synced.step.frequency_hz or 0.0)
    refs = _refs(synced)
    levant = refs["sliding_mode"]
    for name in LINEAR:
        assert np.sqrt(np.mean((levant - refs[name]) ** 2)) > 10.0, name
    ratio = fundamental(levant, f0, fs) / fundamental(refs["smoothed"], f0, fs)
    assert abs(ratio) == pytest.approx(1.0, abs=0.01)


@pytest.mark.parametrize("fs_hz", [150.0, 200.0, 2000.0])
def test_savgol_keeps_a_window_its_quintic_can_fit(fs_hz: float) -> None:
    """25 ms hold 5 samples at 200 Hz, too few for a quintic (SciPy refused, and the
    reference analysis ended the run with an internal error): the window keeps ≥ 7 samples.
    On a 1 Hz sine the estimate is then the true acceleration to the window's truncation
    error, (2πf·w)^6-small: < 1e-6 relative even at 150 Hz (w = 47 ms)."""
    t = np.arange(int(4 * fs_hz)) / fs_hz
    amplitude_deg = 10.0
    position = amplitude_deg * np.sin(2 * np.pi * t)
    truth = -amplitude_deg * (2 * np.pi) ** 2 * np.sin(2 * np.pi * t)
    accel = savgol_accel(position, fs_hz)
    inner = slice(int(0.5 * fs_hz), int(3.5 * fs_hz))  # away from the ends' interpolation
    peak = amplitude_deg * (2 * np.pi) ** 2
    assert np.max(np.abs(accel[inner] - truth[inner])) < 1e-6 * peak
