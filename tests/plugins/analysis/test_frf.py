"""Stepped-sine FRF against a synthetic sensor with known dynamics and delay."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from synthetic_rig import SynthRig, SynthSensor, _sensor_gain, make_dataset, sine_step

from aatest.engine.analysis.passes import run_analysis
from aatest.plugins.analysis.frf import analyse_tone


def test_tone_metrics_of_a_known_signal() -> None:
    fs, n, c = 2000.0, 16384, 40
    t = np.arange(n) / fs
    f = c * fs / n
    rng = np.random.default_rng(3)
    x = (
        2.0 * np.sin(2 * np.pi * f * t)
        + 0.02 * np.sin(2 * np.pi * 3 * f * t)
        + rng.normal(0, 0.01, n)
    )
    tone = analyse_tone(x, f, fs)
    assert tone.coherent
    assert abs(tone.fundamental) == pytest.approx(2.0, rel=1e-3)
    assert tone.thd == pytest.approx(0.01, rel=0.02)
    assert tone.snr_db(1) == pytest.approx(10 * np.log10(2.0 / 1e-4), abs=0.2)


@pytest.fixture(scope="module")
def frf_values():  # type: ignore[no-untyped-def]
    sensor = SynthSensor(natural_frequency_hz=40.0, damping=0.6, delay_s=0.005)
    steps = [sine_step(f"f{c}", c, 100.0) for c in (8, 20, 41, 82)]
    data = make_dataset(steps, SynthRig(sensors=(sensor,)))
    out = run_analysis("frf", data)
    return sensor, out


def test_gain_phase_delay_match_truth(frf_values) -> None:  # type: ignore[no-untyped-def]
    sensor, out = frf_values
    for p in out.result.model_dump()["v_sz"]:
        h = sensor.scale_v_per_dps2 * _sensor_gain(sensor, p["frequency_hz"])
        assert p["gain_db"] == pytest.approx(20 * np.log10(abs(h)), abs=0.01)
        # sync resolves the loggers to ≤ 0.25 ms (edges between DAQ samples): phase follows
        tol_deg = 0.05 + 360 * p["frequency_hz"] * 0.25e-3
        assert p["phase_deg"] == pytest.approx(np.degrees(np.angle(h)), abs=tol_deg)
        truth_delay = -np.angle(h) / (2 * np.pi * p["frequency_hz"])
        assert p["delay_s"] == pytest.approx(truth_delay, abs=0.25e-3)
        assert p["snr_db"] > 40 and p["thd"] < 0.01
        # the table estimate is noise-dominated broadband (docs/method.md §1.2),
        # yet exact at the bin
        assert -30 < p["table_snr_db"] < 0
        assert p["coherent"]
    assert "bode_v_sz" in out.figures


@settings(max_examples=30, deadline=None)
@given(
    amp=st.floats(0.01, 100),
    phase=st.floats(-np.pi, np.pi),
    cycles=st.integers(1, 200),
    h3=st.floats(0, 0.1),
)
def test_tone_fundamental_property(amp: float, phase: float, cycles: int, h3: float) -> None:
    """Any coherent tone: amplitude, phase and THD exact at the bin."""
    fs, n = 2000.0, 4096
    f = cycles * fs / n
    t = np.arange(n) / fs
    x = amp * np.cos(2 * np.pi * f * t + phase) + h3 * amp * np.cos(6 * np.pi * f * t)
    tone = analyse_tone(x, f, fs)
    assert abs(tone.fundamental) == pytest.approx(amp, rel=1e-9)
    assert np.angle(tone.fundamental * np.exp(-1j * phase)) == pytest.approx(0.0, abs=1e-9)
    if 3 * cycles < n // 2:
        assert tone.thd == pytest.approx(h3, abs=1e-9)
