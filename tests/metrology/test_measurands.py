"""GUM budgets agree with a Monte Carlo propagation of the same models (within 10 %)."""

from __future__ import annotations

import math

import pytest
from numpy.testing import assert_allclose

from aatest.metrology.uncertainty.dynamic import (
    frf_gain_measurand,
    frf_phase_measurand,
    misalignment_measurand,
)
from aatest.metrology.uncertainty.gum import Input, Measurand, evaluate, monte_carlo
from aatest.metrology.uncertainty.measurands import (
    RigConstants,
    bias_measurand,
    g_sensitivity_measurand,
    scale_factor_measurand,
    temperature_measurand,
)
from aatest.results import RunResults
from aatest.results.root import StepSummary

C = RigConstants()


def _measurands(results: RunResults) -> dict[str, Measurand | None]:
    sf = scale_factor_measurand(results, "v_sz", C)
    assert sf is not None
    sf_eval = evaluate(sf)
    points = results.analysis.frf["v_sz"]
    return {
        "scale": sf,
        "bias": bias_measurand(results, "v_sz", C),
        "g": g_sensitivity_measurand(results, "v_sz", C,
                                     sf_eval.standard_uncertainty / sf_eval.value),
        "g_nominal_k": g_sensitivity_measurand(results, "v_sy", C, None),
        "tc_bias": temperature_measurand(results, "v_sy", "bias_coefficient_v_per_c", C),
        "tc_scale": temperature_measurand(results, "v_sx", "scale_coefficient_per_c", C),
        "gain_low": frf_gain_measurand(points[0], results, C),
        "gain_high": frf_gain_measurand(points[-1], results, C),
        "phase_high": frf_phase_measurand(points[-1], results, C),
        "misalignment": misalignment_measurand(results, "3", "SX", C),
    }


NAMES = ["scale", "bias", "g", "g_nominal_k", "tc_bias", "tc_scale", "gain_low", "gain_high",
         "phase_high",
         "misalignment"]


@pytest.mark.parametrize("name", NAMES, ids=NAMES)
def test_gum_matches_monte_carlo_within_10pct(results: RunResults, name: str) -> None:
    measurand = _measurands(results)[name]
    assert measurand is not None
    gum = evaluate(measurand)
    mc = monte_carlo(measurand, draws=100_000, seed=11)
    assert gum.standard_uncertainty > 0
    assert "{" not in measurand.name  # names are plain labels
    assert_allclose(mc.standard_uncertainty, gum.standard_uncertainty, rtol=0.10)
    assert_allclose(mc.mean, gum.value, atol=3 * gum.standard_uncertainty)
    assert gum.expanded_uncertainty == pytest.approx(2 * gum.standard_uncertainty)
    shares = sum(gum.share_pct(r) for r in gum.rows)
    assert shares == pytest.approx(100.0, rel=1e-6)


def test_scale_factor_budget_is_physical(results: RunResults) -> None:
    """The fit (±0.069 on 249 (°/s²)/V, ci95), encoder 1″ on 10° (~1.6e-5) and the logger's
    0.1 % gain accuracy (u = 0.058 %, dominating): U in the tenths of a percent."""
    gum = evaluate(_measurands(results)["scale"])
    rows = {r.name: r for r in gum.rows}
    fit_rel = math.hypot(rows["fit_reference"].standard_uncertainty,
                         rows["fit_noise"].standard_uncertainty)
    assert_allclose(fit_rel, 0.069 / 1.96 / 249.13, rtol=1e-3)
    pos = rows["encoder_accuracy"].standard_uncertainty
    assert_allclose(pos, (1 / 3600) / 9.99 / math.sqrt(3), rtol=0.01)
    assert_allclose(rows["logger_gain"].standard_uncertainty, 0.001 / math.sqrt(3), rtol=1e-9)
    assert max(gum.rows, key=gum.share_pct).name == "logger_gain"
    assert 1e-3 < gum.relative_expanded < 5e-3


def test_high_frequency_gain_is_limited_by_the_encoder(results: RunResults) -> None:
    """At 10 Hz, 100 °/s², A = 91″: the encoder error (1″, period 1°) can change by its slope
    bound 1″·2π·360/rev = 0.175 % over the motion, rectangular: it dominates the budget."""
    gum = evaluate(_measurands(results)["gain_high"])
    rows = {r.name: r for r in gum.rows}
    slope = math.radians(1 / 3600) * 360
    assert_allclose(rows["encoder_accuracy"].standard_uncertainty, slope / math.sqrt(3),
                    rtol=1e-9)
    assert max(gum.rows, key=gum.share_pct).name == "encoder_accuracy"


def test_cosine_error_input_moments() -> None:
    """E[cos ε − 1] = sin a/a − 1 and its spread, checked against sampling."""
    a = 0.05
    item = Input("tilt", "tilt", 0.0, a, "cosine_error")
    assert_allclose(item.mean(), -a**2 / 6, rtol=1e-3)
    mc = monte_carlo(Measurand("t", "1", lambda ops, x: x["tilt"], (item,)), 200_000, 5)
    assert_allclose(mc.standard_uncertainty, item.standard_uncertainty(), rtol=0.02)
    assert_allclose(item.standard_uncertainty(), a**2 / math.sqrt(45), rtol=1e-3)


def test_missing_analysis_gives_no_measurand(results: RunResults) -> None:
    results.analysis.scale_factor = None
    results.analysis.misalignment = None
    assert scale_factor_measurand(results, "v_sz", C) is None
    assert misalignment_measurand(results, "1", "SZ", C) is None


def test_scale_factor_prefers_the_analysis_u_of_k(results: RunResults) -> None:
    """When the analysis states u(K) directly (best-line fit), the fit row uses it."""
    entry = results.analysis.scale_factor["v_sz"]
    entry.order, entry.scale_u_v_per_dps2 = 12, 4.25e-8
    gum = evaluate(scale_factor_measurand(results, "v_sz", C))
    fit = [r for r in gum.rows if r.name.startswith("fit_")]
    # (the cosine inputs shift the estimate by ~5e-6 relative: mounting 0.3°)
    assert_allclose(math.hypot(*(r.contribution for r in fit)), 4.25e-8, rtol=1e-4)


def test_static_statistics_from_the_analysis(results: RunResults) -> None:
    """bias_u_v / per-mounting g u from the bias analysis replace the noise estimate, and an
    uncalibrated K contributes its ±1 % datasheet tolerance (rectangular) to g. (Without
    per-mounting repetitions nothing can be pooled; the stated u are used.)"""
    entry = results.analysis.bias["v_sz"]
    entry.bias_u_v = 3.2e-6
    for mounting, u in (("original", 0.0016), ("pivoted", 0.0004)):
        entry.mountings[mounting].repetitions = None
        entry.mountings[mounting].g_sensitivity_u_dps2_per_g = u
    bias = {r.label: r for r in evaluate(bias_measurand(results, "v_sz", C)).rows}
    assert bias["static means (noise, repeatability)"].standard_uncertainty == 3.2e-6
    g = {r.label: r for r in evaluate(g_sensitivity_measurand(results, "v_sz", C, None)).rows}
    assert_allclose(g["static means (noise, repeatability)"].standard_uncertainty,
                    math.hypot(0.0016, 0.0004) / 2, rtol=1e-9)
    assert_allclose(g["scale factor"].contribution, 0.21 * 0.01 / math.sqrt(3), rtol=1e-3)


def test_pooled_mountings_give_the_static_type_a(results: RunResults) -> None:
    """Two mountings of three repetitions each: the Type A of the bias pools within- and
    between-mounting scatter over n = 6 values, with 5 degrees of freedom."""
    entry = results.analysis.bias["v_sz"]
    rows = {r.name: r for r in evaluate(bias_measurand(results, "v_sz", C)).rows}
    within = 2 * (3 - 1) * 3 * 7e-6**2
    between = 2 * 3 * 1.2e-5**2
    expected = math.sqrt((within + between) / 5 / 6)
    # the same sums in another order: a few roundings of ~1e-16 each
    assert_allclose(rows["noise"].standard_uncertainty, expected, rtol=1e-9)
    assert "5 degrees of freedom" in rows["noise"].basis
    assert entry.mountings["original"].repetitions == 3


def test_temperature_coefficients_from_the_columns(results: RunResults) -> None:
    """Columns (temperatures_c, bias_v, branch) give the regression; a stated u wins."""
    from aatest.plugins.report import figures

    entry = results.analysis.temperature["v_sz"]
    regression = evaluate(temperature_measurand(results, "v_sz", "scale_coefficient_per_c", C))
    assert regression.rows[0].basis.startswith("regression over 15")
    entry.bias_coefficient_u_v_per_c = 9.3e-8
    stated = evaluate(temperature_measurand(results, "v_sz", "bias_coefficient_v_per_c", C))
    assert stated.rows[0].standard_uncertainty == 9.3e-8
    assert figures.bias_vs_temperature(entry) is not None


@pytest.mark.parametrize(("segments_rad", "local_rel", "governs"),
                         [(4e-4, 1e-4, "segments"), (1e-4, 4e-4, "neighbour bins")],
                         ids=["segments-larger", "neighbours-larger"])
def test_frf_noise_row_is_the_larger_type_a_with_its_dof(
        results: RunResults, segments_rad: float, local_rel: float, governs: str) -> None:
    """The segments' spread and the neighbour bins' noise estimate the same term, each blind
    where the other sees: the larger one enters, with its own degrees of freedom (the
    segments' few raise k above 2)."""
    point = results.analysis.frf["v_sz"][1]
    point.u_segments_phase_rad = point.u_segments_gain_rel = segments_rad
    point.segments_dof, point.segments, point.cycles_per_segment = 5.7, 7, 2
    point.u_local_rel, point.sample_rate_hz = local_rel, 2000.0
    # the record of the point: 16384 samples (the FRF point states none of its own)
    results.steps = [StepSummary(id=point.step, kind="sine", samples=16384,
                                 frequency_hz=point.frequency_hz, accel_dps2=100.0)]
    measurand = frf_phase_measurand(point, results, C)
    assert measurand is not None
    noise = next(i for i in measurand.inputs if i.name == "noise")
    assert noise.spread == max(segments_rad, local_rel) and noise.kind == "A"
    evaluation = evaluate(measurand)
    if governs == "segments":
        assert noise.dof == pytest.approx(5.7)
        assert "Hann-weighted segments" in noise.note.split(";")[0]
        assert evaluation.k > 2.2
    else:
        # 0.99 Hz in 16384 samples: bin 8; below it bins 5…1, above 11…48 less 16, 24, 32,
        # 40 and 48: 5 + 33 bins
        assert noise.dof == 38.0
        assert "bins 3–40" in noise.note.split(";")[0]
        assert 2.0 < evaluation.k < 2.1
