"""Properties of the GUM engine and the ci95 reader (hypothesis)."""

from __future__ import annotations

import math
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from aatest.metrology.uncertainty.gum import Input, Measurand, evaluate, monte_carlo
from aatest.metrology.uncertainty.statistics import ci_std

finite = st.floats(min_value=-1e3, max_value=1e3, allow_nan=False).filter(lambda v: abs(v) > 1e-3)
spread = st.floats(min_value=1e-6, max_value=10.0)
dist = st.sampled_from(["normal", "rectangular"])


@pytest.mark.pinned
@settings(max_examples=25, deadline=None)
@given(st.lists(st.tuples(finite, spread, dist), min_size=1, max_size=5))
def test_linear_model_is_exact_and_matches_monte_carlo(terms: list[tuple[float, float, str]]
                                                       ) -> None:
    """y = Σ c_i·x_i: u_c = √Σ(c_i·u_i)² exactly, and Monte Carlo agrees within 3 %."""
    inputs = tuple(Input(f"x{i}", f"x{i}", 0.0, s, d)  # type: ignore[arg-type]
                   for i, (_, s, d) in enumerate(terms))
    coefficients = [c for c, _, _ in terms]

    def model(ops: Any, x: Any) -> Any:
        return sum(c * x[f"x{i}"] for i, c in enumerate(coefficients))

    measurand = Measurand("y", "1", model, inputs)
    gum = evaluate(measurand)
    expected = math.sqrt(sum((c * i.standard_uncertainty()) ** 2
                             for c, i in zip(coefficients, inputs, strict=True)))
    assert_allclose(gum.standard_uncertainty, expected, rtol=1e-9)
    assert_allclose(monte_carlo(measurand, 60_000, 1).standard_uncertainty, expected, rtol=0.03)


@given(st.floats(min_value=-1e6, max_value=1e6), st.floats(min_value=0, max_value=1e3))
def test_ci_std_forms_agree(centre: float, half: float) -> None:
    """[lo, hi] gives half-width / 1.96 (a large-sample 95 % interval); an interval that is
    not a pair of finite bounds gives none."""
    pair = ci_std([centre - half, centre + half])
    assert pair is not None
    assert_allclose(pair, half / 1.959963984540054, rtol=1e-6, atol=1e-9)
    assert ci_std([centre, float("nan")]) is None
    assert ci_std([centre]) is None
