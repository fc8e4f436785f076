"""Each budget component against its defining formula, and its basis naming the source."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from numpy.testing import assert_allclose

from aatest.engine.rig_description import Instruments
from aatest.metrology.uncertainty import components as comp
from aatest.metrology.uncertainty.evidence import (
    LINE_SAMPLES,
    Evidence,
    TemperatureEvidence,
    gather,
    local_noise_rel,
    static_line,
)
from aatest.metrology.uncertainty.gum import Input, Measurand, coverage_factor, evaluate
from aatest.metrology.uncertainty.measurands import RigConstants, bias_measurand
from aatest.results import RunResults

STATED = Instruments.model_validate({
    "logger": {"offset_accuracy_v": 0.002, "gain_accuracy_pct": 0.05, "bits": 16,
               "range_v": [-10, 10], "cert_id": "LOG-123", "cert_date": "2026-03-01"},
    "encoder": {"accuracy_arcsec": 2.0, "error_cycles_per_rev": 36},
})


def _constants(instruments: Instruments = STATED, stated: bool = True,
               evidence: Evidence | None = None) -> RigConstants:
    return RigConstants(instruments=instruments, instruments_stated=stated,
                        evidence=evidence or Evidence())


def test_logger_offset_row_is_the_stated_accuracy_over_root_3() -> None:
    row = comp.logger_offset(_constants())
    assert row.standard_uncertainty() == pytest.approx(0.002 / math.sqrt(3))
    assert "rig description: logger offset accuracy ±2 mV (cert LOG-123, 2026-03-01)" in row.note


def test_logger_resolution_16_bit_10_v_is_305_uv_over_root_12() -> None:
    row = comp.logger_resolution_v(_constants())
    assert STATED.logger.step_v == pytest.approx(305.18e-6, rel=1e-4)
    assert row.standard_uncertainty() == pytest.approx(20 / 2**16 / math.sqrt(12))
    assert "305 µV" in row.note


def test_logger_gain_row_is_relative_and_rectangular() -> None:
    row = comp.logger_gain(_constants())
    assert (row.unit, row.distribution) == ("1", "rectangular")
    assert row.standard_uncertainty() == pytest.approx(0.0005 / math.sqrt(3))


def test_defaults_are_named_as_such() -> None:
    row = comp.logger_gain(_constants(Instruments(), stated=False))
    assert row.note.startswith("stated default: logger gain accuracy 0.1 %")


def test_encoder_accuracy_is_bounded_by_the_error_slope() -> None:
    """a/A for a large motion; the slope bound a·2π·n/rev once A exceeds the error period."""
    c = _constants()
    small = comp.encoder_accuracy(c, amplitude_arcsec=100.0)
    slope = math.radians(2 / 3600) * 36
    assert small.spread == pytest.approx(min(2 / 100.0, slope))
    large = comp.encoder_accuracy(c, amplitude_arcsec=1e6)
    assert large.spread == pytest.approx(2e-6)


def test_encoder_resolution_is_one_count_over_root_12() -> None:
    c = _constants()
    row = comp.encoder_resolution(c, amplitude_arcsec=3600.0)
    q = 360 * 3600 / STATED.encoder.resolution_counts_per_rev
    assert row.standard_uncertainty() == pytest.approx(q / math.sqrt(12) / 3600.0)


def test_temperature_logged_vs_not_logged() -> None:
    """Logged: TC × √(u_T² + s²) at the logged temperature; else TC × lab tolerance (rect)."""
    logged = Evidence(temperature={"s1": TemperatureEvidence(22.0, 0.05)}, recording=True)
    row, at = comp.temperature(_constants(evidence=logged), ["s1"], 0.0005, "TC", "1")
    u_t = math.hypot(0.2 / math.sqrt(3), 0.05)
    assert row.standard_uncertainty() == pytest.approx(0.0005 * u_t)
    assert "22.0 °C (logged)" in at
    row, at = comp.temperature(_constants(), ["s1"], 0.0005, "TC", "1")
    assert row.distribution == "rectangular" and row.spread == pytest.approx(0.0005 * 3.0)
    assert "not logged" in row.note and "reference temperature" in at


def test_mounting_uses_a_misalignment_result_of_the_run() -> None:
    stated = comp.mounting(_constants(), RunResults(procedure="p"), "v_sz")
    assert stated.spread == pytest.approx(math.radians(0.3)) and "mounting accuracy" in stated.note
    results = RunResults.model_validate({"procedure": "p", "analysis": {"misalignment": {
        "scenarios": {"1": {"SZ": {"delta_deg": 0.05, "A_S": [0.4, 0.0],
                                   "expanded_uncertainty": 0.01}}}, "sets": {}}}})
    measured = comp.mounting(_constants(), results, "v_sz")
    assert measured.spread == pytest.approx(math.radians(0.06))
    assert measured.note.startswith("measured: misalignment result")


def test_not_evaluated_rows_show_as_such() -> None:
    row = comp.not_evaluated("repeatability", "repeatability", "no repeated steps")
    evaluation = evaluate(Measurand("q", "1", lambda ops, x: 1.0 + x["repeatability"], (row,)))
    shown = evaluation.rows[0]
    assert (shown.evaluated, shown.contribution) == (False, 0.0)
    assert shown.basis == "not evaluated: no repeated steps"


def test_reference_method_from_the_reference_analysis() -> None:
    compared = {m: {"gain": g, "rms_diff_dps2": 0.1, "runtime_s": 0.01}
                for m, g in (("smooth", 1.0), ("savgol", 1.0003), ("table", 0.9999))}
    results = RunResults.model_validate({"procedure": "p",
                                         "analysis": {"reference": {"s1": compared}}})
    row = comp.reference_method(results, ["s1"], "smoothed")
    assert row.spread == pytest.approx(3e-4)
    assert "(polynomial fit of the position vs smoothed position)" in row.note
    missing = comp.reference_method(RunResults(procedure="p"), ["s1"], "smoothed")
    assert not missing.evaluated


def test_bias_budget_holds_the_logger_offset(results: RunResults) -> None:
    """The bias U can never be smaller than the logger's offset accuracy contribution."""
    c = _constants()
    measurand = bias_measurand(results, "v_sz", c)
    assert measurand is not None
    evaluation = evaluate(measurand)
    rows = {r.name: r for r in evaluation.rows}
    offset = rows["logger_offset"]
    assert offset.contribution == pytest.approx(0.002 / math.sqrt(3))
    assert evaluation.expanded_uncertainty >= 2 * offset.contribution
    assert "logger_gain" in rows and "logger_resolution" in rows


def test_welch_satterthwaite_widens_k_for_few_degrees_of_freedom() -> None:
    assert coverage_factor(1.0, [(1.0, math.inf)]) == 2.0
    k5 = coverage_factor(1.0, [(1.0, 5.0)])
    assert 2.6 < k5 < 2.7  # t(95.45 %, 5) = 2.65
    item = Input("a", "a", 0.0, 1.0, dof=5.0)
    assert evaluate(Measurand("q", "1", lambda ops, x: x["a"], (item,))).k == pytest.approx(k5)


@pytest.mark.parametrize("dof", [0.7, 1.0, 2.5, 5.0, 14.2, 60.0, 1e4, 1e9])
def test_k_is_the_t_quantile_scipy_stats_gives(dof: float) -> None:
    # the special functions are called directly: the values of norm.cdf and t.ppf. Both
    # sides invert the t CDF iteratively, from the same q and ν_eff, and may end the
    # inversion in other last bits (its scalar and array paths are 1 ulp apart at ν = 1e9
    # here); scipy's own tests hold that inversion to 1e-7 only, so no bound in ε is
    # promised on another build. What the test must tell apart is the quantile of another
    # ν_eff (a Welch–Satterthwaite slip) or the normal one: a relative error r in ν_eff moves
    # k by ≈ r·(k − z), z the normal quantile. Allowed: 1 % of (k − z)/k, so ν_eff is pinned
    # to ≈ 1 % (5e-12 at ν = 1e9, ≥ 5e-7 below 1e4), ~10⁴ × the inversion's error measured
    # against an exact quantile (mpmath, 40 digits: ≤ 3.3e-16 for these ν).
    from scipy.stats import norm, t

    u_i, u_c = 0.8, 1.0
    dof_eff = u_c**4 / (u_i**4 / dof)  # Welch–Satterthwaite, as coverage_factor forms it
    q = 0.5 + (2.0 * norm.cdf(2.0) - 1.0) / 2.0
    expected = float(max(2.0, t.ppf(q, dof_eff)))
    rel = 0.01 * (expected - float(norm.ppf(q))) / expected
    assert coverage_factor(u_c, [(u_i, dof)]) == pytest.approx(expected, rel=rel, abs=0)


def test_local_bin_noise_and_static_lines_are_measured() -> None:
    """Noise next to a bin (white noise σ over N: √(2/N)·σ/A), and a line's residual bound."""
    rng = np.random.default_rng(7)
    n, cycles, amp, sigma = 16384, 64, 2.0, 0.01
    t = np.arange(n)
    x = amp * np.sin(2 * np.pi * cycles * t / n) + sigma * rng.standard_normal(n)
    assert_allclose(local_noise_rel(x, cycles), sigma * math.sqrt(2.0 / n) / amp, rtol=0.2)
    fs = 2000.0
    tone = 2.5 + 0.024 * np.sin(2 * np.pi * 35.0 * np.arange(4000) / fs + 0.3)
    line = static_line(tone, fs)
    assert line is not None
    assert line.frequency_hz == pytest.approx(35.0, abs=0.5)
    assert line.amplitude_v == pytest.approx(0.024, rel=0.05)
    assert line.residual_bound_v == pytest.approx(0.024 / (math.pi * 35.0 * 2.0), rel=0.05)


@pytest.mark.pinned
def test_a_long_static_record_is_searched_on_its_head_but_bounded_over_its_length() -> None:
    """Past LINE_SAMPLES the line is read off the first 2**20 samples (the same line as on
    the head alone); its residual bound is over the whole record's duration."""
    fs, n = 2000.0, LINE_SAMPLES + LINE_SAMPLES // 2
    t = np.arange(n) / fs
    rng = np.random.default_rng(9)
    volts = 2.5 + 0.03 * np.sin(2 * np.pi * 35.0 * t) + 1e-4 * rng.standard_normal(n)
    line, head = static_line(volts, fs), static_line(volts[:LINE_SAMPLES], fs)
    assert line is not None and head is not None
    assert (line.amplitude_v, line.frequency_hz) == (head.amplitude_v, head.frequency_hz)
    assert line.frequency_hz == pytest.approx(35.0, abs=0.01)
    assert line.amplitude_v == pytest.approx(0.03, rel=0.01)
    # the same line's bound scaled by a ratio of two integers: a few roundings, exact otherwise
    assert line.residual_bound_v == pytest.approx(head.residual_bound_v * LINE_SAMPLES / n,
                                                  rel=1e-12)


def test_evidence_from_partial_decodes_equals_the_whole_steps() -> None:
    """gather() decodes only the channels it reads from a recording; nothing it measures
    changes against the same steps decoded whole."""
    from pathlib import Path

    from aatest.recording import read_dataset
    from aatest.recording.dataset import Dataset, LazySteps

    lazy = read_dataset(Path(__file__).parents[1] / "recording" / "data" / "streaming"
                        / "recording.mcap")
    assert isinstance(lazy.steps, LazySteps)
    eager = Dataset(procedure=lazy.procedure, sample_rate_hz=lazy.sample_rate_hz,
                    sensors=lazy.sensors, steps=tuple(lazy.steps), source=lazy.source,
                    metadata=lazy.metadata)
    partial, whole = gather(lazy), gather(eager)
    assert partial.motion and partial.bin_noise and partial.temperature
    assert partial == whole


@pytest.mark.pinned
def test_a_recorded_static_step_is_summarised_piece_by_piece(tmp_path: Any) -> None:
    """A recorded static step is read block by block: its line is the one of the whole
    record, its temperature mean and spread agree with NumPy's on the whole to rounding."""

    from recording_data import SENSOR, table_log

    from aatest.engine.logs import SampledLog
    from aatest.engine.steps import PlannedStep
    from aatest.recording import RunRecorder, read_dataset
    from aatest.recording.dataset import Dataset

    fs, n = 2000.0, 60_001
    step = PlannedStep(id="s01-static", kind="static", samples=n, duration_s=n / fs,
                       sample_rate_hz=fs)
    rng = np.random.default_rng(12)
    t = np.arange(n) / fs
    daq = SampledLog("daq", fs, t, {
        "v_sz": 2.5 + 0.02 * np.sin(2 * np.pi * 35.0 * t) + rng.normal(0, 1e-3, n),
        "trigger": np.ones(n), "temperature_c": 23.0 + 0.5 * t / t[-1] + rng.normal(0, 0.01, n),
    }, {"v_sz": "V", "temperature_c": "degC"})
    recorder = RunRecorder(tmp_path)
    recorder.write_run_metadata({"procedure": "static", "sensors": [vars(SENSOR)]})
    recorder.write_step(step, table_log(step, rng), daq)
    lazy = read_dataset(recorder.finalize())
    streamed = gather(lazy)
    whole = gather(Dataset(procedure="static", sample_rate_hz=fs, sensors=lazy.sensors,
                           steps=tuple(lazy.steps), source=lazy.source))
    assert streamed.static_lines == whole.static_lines
    line = streamed.static_lines["s01-static"]["v_sz"]
    assert line.frequency_hz == pytest.approx(35.0, abs=0.05)
    got, expected = streamed.temperature["s01-static"], whole.temperature["s01-static"]
    assert expected.mean_c == float(np.mean(daq["temperature_c"]))
    # block-by-block vs whole-array sums of same-sign samples: each rounds to ≲ ε·log2(n)
    # ≈ 4e-15 of the sum, whatever the SIMD width; 1e-13 keeps a factor 25 above that
    assert got.mean_c == pytest.approx(expected.mean_c, rel=1e-13)
    # the spread subtracts the mean (condition x̄/s ≈ 23 °C / 0.3 °C ≈ 80 on the deviations)
    assert got.std_c == pytest.approx(expected.std_c, rel=1e-11)


def test_evidence_measured_while_the_analyses_decode_equals_its_own_decodes() -> None:
    """watch(): the sync pass's partial decodes also measure the sine steps' evidence; gather()
    then decodes no sine step again, and what it reports is what its own decodes give."""
    from pathlib import Path

    from aatest.metrology.uncertainty.evidence import watch
    from aatest.plugins.analysis.sync import _SYNC_CHANNELS
    from aatest.recording import read_dataset
    from aatest.recording.dataset import LazySteps

    path = Path(__file__).parents[1] / "recording" / "data" / "streaming" / "recording.mcap"
    plain, watched = read_dataset(path), read_dataset(path)
    assert isinstance(watched.steps, LazySteps)
    watch(watched)
    sine = [i for i, p in enumerate(watched.planned) if p.kind == "sine"]
    for i in sine:
        part = watched.steps.partial(i, _SYNC_CHANNELS)
        assert set(part.table.channels) == set(_SYNC_CHANNELS["table"])  # the caller's only
    decodes: list[int] = []
    load = watched.steps._load
    watched.steps._load = lambda i, s, c: decodes.append(i) or load(i, s, c)  # type: ignore
    found = gather(watched)
    assert not set(decodes) & set(sine)
    assert found.motion and found.bin_noise
    assert found == gather(plain)
