"""Stepped-sine FRF against a synthetic sensor with known dynamics and delay."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from synthetic_rig import SynthRig, SynthSensor, _sensor_gain, make_dataset, sine_step

from aatest.engine.analysis.passes import run_analysis
from aatest.plugins.analysis import frf
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


@pytest.mark.pinned
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


def _tone(amplitude: complex, frequency_hz: float, t_s: np.ndarray) -> np.ndarray:
    """Re(amplitude·e^{jωt}): a tone whose complex fundamental is ``amplitude``."""
    return np.real(amplitude * np.exp(2j * np.pi * frequency_hz * t_s))


@settings(max_examples=30, deadline=None)
@given(cycles=st.floats(6.0, 300.0), phase=st.floats(-np.pi, np.pi),
       gain=st.floats(0.001, 10.0), h2=st.floats(0.0, 0.2), h5=st.floats(0.0, 0.1),
       dc=st.floats(-3.0, 3.0))
def test_segmented_ratio_is_exact_for_periodic_content(cycles: float, phase: float, gain: float,
                                                      h2: float, h5: float, dc: float) -> None:
    """Whole cycles or not (a period of a non-integer number of samples), the fit of the mean
    and the harmonics leaves the ratio of the fundamentals exact."""
    fs, n = 2000.0, 8192
    f = cycles * fs / n
    t = np.arange(n) / fs
    reference = _tone(100.0 - 30.0j, f, t) + h2 * 100.0 * np.cos(4 * np.pi * f * t) + dc
    truth = gain * np.exp(1j * phase)
    output = (_tone(truth * (100.0 - 30.0j), f, t) + h5 * np.sin(10 * np.pi * f * t + 1.0)
              + 2.5 + dc)
    seg = frf.segmented_ratio(reference, output, f, fs)
    assert seg.segments >= 2
    assert abs(seg.ratio / truth - 1.0) < 1e-9
    assert seg.u_phase_rad is not None and seg.u_phase_rad < 1e-9


def test_segment_layout_keeps_whole_cycles_and_two_per_segment() -> None:
    fs, n = 2000.0, 16384
    # 8 cycles (the coverage bench's 0.98 Hz): one-cycle segments were biased, so 2 × 7
    length, hop, count = frf.segment_layout(n, 8 * fs / n, fs)
    assert (length, hop, count) == (4096, 2048, 7)
    # 33 cycles: ≈15 segments of 4 cycles (1985.9 samples each, rounded)
    length, hop, count = frf.segment_layout(n, 33 * fs / n, fs)
    assert (length, count) == (1986, 15) and hop == length // 2


def test_segment_type_a_matches_the_scatter_of_white_noise() -> None:
    """The overlap-corrected standard error equals the record-to-record scatter of the mean
    (seeded white noise on output and reference; without the correction for the 50 %
    overlap it would be ≈14 % low, which the bounds reject)."""
    rng = np.random.default_rng(2026)
    fs, n, f = 2000.0, 8192, 37 * 2000.0 / 8192
    t = np.arange(n) / fs
    clean_x, clean_y = _tone(100.0, f, t), _tone(0.4 * np.exp(-0.3j), f, t)
    ratios, u_phase, u_gain = [], [], []
    for _ in range(300):
        seg = frf.segmented_ratio(clean_x + rng.normal(0, 20.0, n),
                                  clean_y + rng.normal(0, 0.06, n), f, fs)
        assert seg.u_phase_rad is not None and seg.u_gain_rel is not None
        ratios.append(seg.ratio)
        u_phase.append(seg.u_phase_rad)
        u_gain.append(seg.u_gain_rel)
    rel = np.array(ratios) / (0.4 * np.exp(-0.3j) / 100.0) - 1.0
    assert np.std(rel.imag) / np.sqrt(np.mean(np.square(u_phase))) == pytest.approx(1.0, abs=0.1)
    assert np.std(rel.real) / np.sqrt(np.mean(np.square(u_gain))) == pytest.approx(1.0, abs=0.1)
