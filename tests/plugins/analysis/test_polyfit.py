"""Least-squares statistics and MATLAB's model-quality metrics."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from aatest.plugins.analysis import polyfit


def test_matlab_tfest_metrics() -> None:
    """Published tfest example: V = 1.6575, N = 300, n_p = 6 → FPE 1.7252, nAIC 0.5453."""
    assert polyfit.fpe(1.6575, 6, 300) == pytest.approx(1.7252, abs=5e-5)
    assert polyfit.naic(1.6575, 6, 300) == pytest.approx(0.5453, abs=5e-5)


def test_fit_percent_definition() -> None:
    y = np.array([1.0, 2.0, 3.0, 4.0])
    assert polyfit.fit_percent(y, y) == 100.0
    assert polyfit.fit_percent(y, np.full(4, y.mean())) == pytest.approx(0.0)


@settings(max_examples=25, deadline=None)
@given(st.lists(st.floats(-50, 50), min_size=1, max_size=4), st.integers(0, 2**31))
def test_polynomial_recovered_with_honest_bounds(coefs: list[float], seed: int) -> None:
    rng = np.random.default_rng(seed)
    u = rng.uniform(-1.6, 1.6, 4000)
    y = np.polynomial.polynomial.polyval(u, coefs) + rng.normal(0, 0.5, u.size)
    fit = polyfit.fit_polynomial(u, y, len(coefs) - 1)
    assert_allclose(fit.coefficients, coefs, atol=6 * fit.std_errors.max() + 1e-9)
    assert 0.45 < fit.rmse < 0.55
    assert np.all(fit.ci95[:, 0] <= fit.ci95[:, 1])


def test_high_order_is_well_conditioned_and_order_choice() -> None:
    rng = np.random.default_rng(2)
    u = rng.uniform(-2, 2, 20000)
    y = 250 * u + 3 * u**3 + rng.normal(0, 1.0, u.size)
    fit15 = polyfit.fit_polynomial(u, y, 15)
    assert fit15.rmse == pytest.approx(1.0, rel=0.03)
    table = polyfit.cross_validate(u, y, max_order=8, seed=1)
    assert polyfit.choose_order(table) == 3


def test_nonlinearity_of_a_line_is_zero() -> None:
    u = np.linspace(-1, 1, 100)
    fit = polyfit.fit_polynomial(u, 2 * u + 1, 1)
    assert polyfit.nonlinearity(fit, -1, 1) < 1e-9


def test_linearity_l_is_the_rms_distance_from_the_ideal_line() -> None:
    """Eq. 3.36 on exact curves: a line offset by 0.5 from the ideal line is 0.5 away; u³ on
    uniform [−1, 1] against its best line 0.6·u is sqrt(1/7 − 0.24 + 0.12) away
    (E[u⁶] − 1.2·E[u⁴] + 0.36·E[u²]); the mean over 20000 midpoints is that integral to
    ≈ 1e-8 (midpoint rule, error ∝ 1/N²)."""
    u = (np.arange(20000) + 0.5) / 10000.0 - 1.0
    line = polyfit.fit_polynomial(u, 2.0 * u + 0.5, 1)
    assert polyfit.linearity_l(line, u, np.array([0.0, 2.0])) == pytest.approx(0.5, rel=1e-9)
    assert polyfit.linearity_l(line, u, line.coefficients) < 1e-9
    cubic = polyfit.fit_polynomial(u, u**3, 3)
    expected = np.sqrt(1 / 7 - 0.24 + 0.12)
    assert polyfit.linearity_l(cubic, u, np.array([0.0, 0.6])) == pytest.approx(expected,
                                                                                 rel=1e-4)
