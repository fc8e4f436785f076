"""Castrup's variables-data interval against hand computations (H. Castrup, NCSLI 2005)."""

from __future__ import annotations

import math
from datetime import UTC, datetime, timedelta

import numpy as np
import pytest
from scipy import stats

from aatest.engine.errors import AnalysisError
from aatest.fleet.interval import (
    DriftSample,
    drift_samples,
    fit_deviation,
    recommend_interval,
)
from aatest.records.models import CalibrationRecord, QuantityRecord

T0 = datetime(2024, 1, 1, tzinfo=UTC)
# Deviations of three calibration intervals (elapsed days, as-found − as-left), no U stated.
DAYS = (100.0, 200.0, 300.0)
DEVIATIONS = (0.1, 0.2, 0.33)


def _unweighted() -> list[DriftSample]:
    return [DriftSample(t, y, None) for t, y in zip(DAYS, DEVIATIONS, strict=True)]


def test_unweighted_line_through_the_origin_matches_the_hand_computation() -> None:
    fit = fit_deviation(_unweighted())
    # By hand: Σty = 10 + 40 + 99 = 149, Σt² = 10⁴ + 4·10⁴ + 9·10⁴ = 14·10⁴,
    # b = 149 / 140000 = 1.0642857e-3 per day.
    b = 149.0 / 140000.0
    # Residuals y − bt: 0.1 − 0.10642857, 0.2 − 0.21285714, 0.33 − 0.31928571;
    # s² = Σr² / (n − m) = Σr² / 2; var(b) = s² / Σt².
    r = np.array([0.1 - 100 * b, 0.2 - 200 * b, 0.33 - 300 * b])
    s2 = float(r @ r) / 2.0
    # a 1×1 normal equation: only rounding (~1e-15) separates the two; 1e-9 leaves room
    assert fit.coefficients[0] == pytest.approx(b, rel=1e-9)
    assert fit.s == pytest.approx(math.sqrt(s2), rel=1e-9)
    assert fit.covariance[0, 0] == pytest.approx(s2 / 140000.0, rel=1e-9)
    assert fit.dof == 2
    assert not fit.weighted


def test_one_sided_interval_solves_the_hand_quadratic() -> None:
    """With the lower limit far away, R(T) = F₂((L₂ − x₀ − bT) / u(T)) = R*, so
    (D − bT)² = k²(u₀² + s² + T² var b) with D = L₂ − x₀ and k = t₂⁻¹(R*): a quadratic in T."""
    fit = fit_deviation(_unweighted())
    x_left, u_left, upper, target = 0.0, 0.05, 1.0, 0.95
    b, s2, var_b = fit.coefficients[0], fit.s**2, fit.covariance[0, 0]
    k = stats.t.ppf(target, 2)  # 2.919986 for ν = 2
    d, a = upper - x_left, u_left**2 + s2
    qa, qb, qc = b * b - k * k * var_b, -2.0 * d * b, d * d - k * k * a
    roots = sorted((-qb + sign * math.sqrt(qb * qb - 4 * qa * qc)) / (2 * qa) for sign in (1, -1))
    expected = next(t for t in roots if t > 0 and d - b * t > 0)
    found = recommend_interval(fit, x_left, u_left, (-1e6, upper), target)
    # Brent's method stops at a thousandth of a day (xtol); R's slope there is well conditioned
    assert found.days == pytest.approx(expected, abs=2e-3)
    assert 700 < expected < 800  # ~26 months: what the numbers above give
    assert found.reliability(found.days)[0] == pytest.approx(target, abs=1e-6)


def test_two_sided_reliability_is_the_student_t_probability_between_the_limits() -> None:
    fit = fit_deviation(_unweighted())
    x_left, u_left, limits, target = 0.2, 0.03, (-0.5, 0.9), 0.9
    found = recommend_interval(fit, x_left, u_left, limits, target)
    assert found.days is not None
    # By hand at the interval T: μ = x₀ + bT, σ² = u₀² + s² + T² var b, ν = 2, and
    # R = F₂((L₂ − μ)/σ) − F₂((L₁ − μ)/σ) must equal the target (Brent's xtol in days times
    # R's slope, < 1e-3 per day here, bounds the difference far below 1e-5)
    t = found.days
    mu = x_left + fit.coefficients[0] * t
    sigma = math.sqrt(u_left**2 + fit.s**2 + t * t * fit.covariance[0, 0])
    by_hand = stats.t.cdf((0.9 - mu) / sigma, 2) - stats.t.cdf((-0.5 - mu) / sigma, 2)
    assert by_hand == pytest.approx(target, abs=1e-5)
    # and the first crossing: R is above the target everywhere before it
    assert (found.reliability(np.linspace(0.0, t * 0.999, 200)) > target).all()


def test_weighted_slope_is_the_inverse_variance_mean() -> None:
    samples = [DriftSample(100.0, 0.10, 0.01), DriftSample(200.0, 0.22, 0.02),
               DriftSample(300.0, 0.29, 0.01)]
    fit = fit_deviation(samples)
    # By hand: w ∝ 1/u² = (1, 1/4, 1) (scale cancels in b):
    # b = Σwty / Σwt² = (10 + 11 + 87) / (10⁴ + 10⁴ + 9·10⁴) = 108 / 110000.
    assert fit.coefficients[0] == pytest.approx(108.0 / 110000.0, rel=1e-9)
    assert fit.weighted


def test_deviations_pair_each_as_found_with_the_previous_as_left() -> None:
    def record(i: int, days: int, value: float, u: float) -> CalibrationRecord:
        when = T0 + timedelta(days=days)
        return CalibrationRecord(
            id=i, model="m", serial="S", certificate_number=None, supersedes_id=None,
            superseded_by=None, command="run", procedure="p", procedure_sha256=None,
            operator=None, lab="L", calibrated_utc=when, registered_utc=when,
            overall_verdict="pass", verdicts=[], bundle=f"/b/{i}", key_fingerprint=None,
            files={}, quantities={"q.c": QuantityRecord(value=value, expanded_uncertainty=u,
                                                         unit="V")}, rig={},
            plugin_versions={})

    records = [record(1, 0, 1.00, 0.02), record(2, 365, 1.03, 0.04), record(3, 730, 1.01, 0.02)]
    # the second calibration adjusted the unit back to 1.00: the third interval starts there
    samples = drift_samples(records, "q.c", {2: {"q.c": 1.00}})
    assert [s.elapsed_days for s in samples] == [365.0, 365.0]
    assert [s.deviation for s in samples] == pytest.approx([0.03, 0.01], abs=1e-12)
    # u = √((U₁/2)² + (U₂/2)²) = √(0.01² + 0.02²)
    assert samples[0].u_deviation == pytest.approx(math.hypot(0.01, 0.02), rel=1e-9)


def test_a_unit_already_outside_its_target_gets_no_interval() -> None:
    fit = fit_deviation(_unweighted())
    found = recommend_interval(fit, 0.99, 0.05, (-1.0, 1.0), 0.95)
    assert found.days == 0.0


def test_no_drift_and_little_scatter_keeps_the_unit_beyond_the_horizon() -> None:
    samples = [DriftSample(t, y, None) for t, y in ((100, 1e-4), (200, -1e-4), (300, 0.0))]
    found = recommend_interval(fit_deviation(samples), 0.0, 1e-3, (-1.0, 1.0), 0.95)
    assert found.days is None


@pytest.mark.parametrize(("count", "degree"), [(1, 1), (2, 2)])
def test_too_few_intervals_are_refused(count: int, degree: int) -> None:
    with pytest.raises(AnalysisError, match="needs at least"):
        fit_deviation(_unweighted()[:count], degree)


def test_bad_target_and_limits_are_refused() -> None:
    fit = fit_deviation(_unweighted())
    with pytest.raises(AnalysisError, match="reliability target"):
        recommend_interval(fit, 0.0, 0.0, (-1.0, 1.0), 1.0)
    with pytest.raises(AnalysisError, match="tolerance limits"):
        recommend_interval(fit, 0.0, 0.0, (1.0, -1.0), 0.9)


def test_a_quadratic_drift_is_recovered_by_the_degree_two_fit() -> None:
    # exact data on y = 1e-3·t + 2e-6·t²: the fit reproduces both terms, the scatter is zero
    samples = [DriftSample(t, 1e-3 * t + 2e-6 * t * t, None) for t in (90.0, 180.0, 270.0, 400.0)]
    fit = fit_deviation(samples, degree=2)
    # a 2×2 normal equation with t up to 400: condition ~1e6, so ~1e-10 relative rounding
    assert fit.coefficients == pytest.approx([1e-3, 2e-6], rel=1e-7)
    assert fit.s == pytest.approx(0.0, abs=1e-12)
    assert fit.dof == 2
