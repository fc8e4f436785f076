"""The tolerances of every comparison against a committed reference live in one module,
``tests/tolerances.py``, each with the reason that derives it."""

from __future__ import annotations

import re

import pytest
from tolerances import DEFAULT_REL, REFERENCE_RULES, RULES, tolerance


@pytest.mark.parametrize("rules", [RULES, REFERENCE_RULES], ids=["machines", "reference"])
def test_every_rule_compiles_and_says_why(rules: tuple) -> None:
    for rule in rules:
        re.compile(rule.pattern)
        assert rule.rel >= 0 and rule.abs >= 0 and (rule.rel or rule.abs)
        assert len(rule.reason) > 20, rule.pattern


@pytest.mark.parametrize(("path", "rel", "abs_"), [
    ("analysis.scale_factor.v_sz.fit.rmse_dps2", 1e-3, 1e-12),  # the first matching class
    ("analysis.transfer_function.v_sz.models[0].V", 1e-5, 1e-12),
    ("analysis.drift.v_sz.allan_fit.b", 1e-6, 1e-15),
    ("analysis.bias.v_sz.residual_v", 1e-7, 1e-14),
    ("analysis.scale_factor.v_sz.nonlinearity_dps2", 1e-9, 1e-9),
    ("analysis.sync.drift_spread_ppm", 1e-9, 1e-6),
    ("analysis.bias.v_sz.bias_v", DEFAULT_REL, 0.0),
    ("x.analysis.transfer_function.v", DEFAULT_REL, 0.0),  # classes are anchored at the root
])
def test_reference_comparison_classes(path: str, rel: float, abs_: float) -> None:
    rule = tolerance(path, REFERENCE_RULES)
    assert (rule.rel, rule.abs) == (rel, abs_)
