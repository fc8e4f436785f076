"""The verdict stage: ILAC-G8 decision rules, one source of limits, the overall verdict."""

from __future__ import annotations

import copy
from typing import Any

import pytest
from contract_results import decided, make_results
from pydantic import ValidationError

from aatest.engine.interfaces import SensorDatasheet
from aatest.engine.procedure.models import Acceptance, AcceptanceLimits
from aatest.metrology.verdicts import decide, failed, overall
from aatest.metrology.verdicts_limits import g_sensitivity_limit_dps2_per_g, limits
from aatest.results.base import Verdict

CASES = [  # value, limit, U, rule, verdict
    (0.9, 1.0, 0.05, "simple", "pass"), (1.1, 1.0, 0.05, "simple", "fail"),
    (-1.1, 1.0, 0.0, "simple", "fail"), (0.99, 1.0, 0.05, "simple", "pass"),
    (0.9, 1.0, 0.05, "guarded", "pass"), (0.97, 1.0, 0.05, "guarded", "conditional-pass"),
    (1.03, 1.0, 0.05, "guarded", "conditional-fail"), (1.1, 1.0, 0.05, "guarded", "fail"),
    (-0.97, 1.0, 0.05, "guarded", "conditional-pass"), (0.97, 1.0, None, "guarded", "pass"),
    (0.9, 1.0, 0.05, "shared-risk", "pass"), (0.97, 1.0, 0.05, "shared-risk", "conditional-pass"),
    (1.03, 1.0, 0.05, "shared-risk", "conditional-fail"), (1.1, 1.0, 0.05, "shared-risk", "fail"),
]


@pytest.mark.parametrize(("value", "limit", "u", "rule", "expected"), CASES,
                         ids=[f"{c[3]}-{c[0]}-{c[4]}" for c in CASES])
def test_decision_rules(value: float, limit: float, u: float | None, rule: Any,
                        expected: str) -> None:
    assert decide(value, limit, u, rule) == expected


def test_g_sensitivity_limit_computed_once() -> None:
    """0.1 % FR/g or 0.01 rad/s²/g, whichever is greater; a stated limit wins."""
    assert g_sensitivity_limit_dps2_per_g(SensorDatasheet(model="m")) == pytest.approx(1.1459156)
    wide = SensorDatasheet(model="m", range_dps2=2000.0)
    assert g_sensitivity_limit_dps2_per_g(wide) == pytest.approx(4.0)
    stated = SensorDatasheet(model="m", g_sensitivity_limit_dps2_per_g=0.3)
    assert g_sensitivity_limit_dps2_per_g(stated) == 0.3


def test_procedure_overrides_the_datasheet() -> None:
    acceptance = Acceptance.model_validate({"limits": {"bias_deviation_v": 0.002}})
    resolved = limits(SensorDatasheet(model="m", scale_tolerance_pct=0.5), acceptance)
    assert resolved["bias_deviation_v"] == 0.002 and resolved["scale_factor_deviation_pct"] == 0.5
    assert set(resolved) == set(AcceptanceLimits.model_fields)


def _verdict(value: str, rule: Any = "simple") -> Verdict:
    return Verdict(quantity="bias_deviation_v", channel="v_sz", value=0.0, limit=1.0,
                   rule=rule, verdict=value)  # type: ignore[arg-type]


def test_overall_is_the_worst() -> None:
    assert overall([]) == "none"
    assert overall([_verdict("pass"), _verdict("conditional-pass")]) == "conditional-pass"
    assert overall([_verdict("conditional-fail"), _verdict("fail"), _verdict("pass")]) == "fail"


def test_results_verdicts_and_exit_decision() -> None:
    """Judged on the engine's U: a scale factor 0.18 % off fails a 0.1 % limit; under
    ``guarded`` a limit within U of the value is conditional, and only a conditional fail
    under ``guarded`` (or a fail) makes the run fail."""
    raw = make_results()
    del raw["analysis"]["misalignment"]
    strict = decided(copy.deepcopy(raw), Acceptance.model_validate(
        {"limits": {"scale_factor_deviation_pct": 0.1}}))
    rows = {(v.quantity, v.channel): v for v in strict.verdicts}
    sx = rows[("scale_factor_deviation_pct", "v_sx")]
    # 100·(K/K_nominal − 1) of K = K_nominal·(1 − 0.0018): a few roundings
    assert sx.verdict == "fail" and sx.value == pytest.approx(-0.18, abs=1e-9)
    assert rows[("scale_factor_deviation_pct", "v_sz")].verdict == "pass"
    noise = rows[("noise_rms_v", "v_sz")]
    assert (noise.value, noise.limit, noise.verdict) == (0.00101, 0.003, "pass")
    assert strict.overall == "fail" and failed(strict)
    u = sx.expanded_uncertainty
    assert u is not None
    assert 0 < u < 0.18  # the budget holds the logger's 0.1 % gain accuracy (issue 11)
    near = {"rule": "guarded", "limits": {"scale_factor_deviation_pct": 0.18 - u / 2}}
    guarded = decided(copy.deepcopy(raw), Acceptance.model_validate(near))
    sx = next(v for v in guarded.verdicts if v.quantity == "scale_factor_deviation_pct"
              and v.channel == "v_sx")
    assert sx.verdict == "conditional-fail" and guarded.overall == "conditional-fail"
    assert failed(guarded)
    shared = decided(copy.deepcopy(raw), Acceptance.model_validate({**near, "rule": "shared-risk"}))
    assert shared.overall == "conditional-fail" and not failed(shared)


def test_missing_contract_key_is_an_error() -> None:
    """A result without a key the contract promises does not become a typed record (the
    error names where it is), so no stage can silently lose its budget or verdict."""
    raw = make_results()
    del raw["analysis"]["scale_factor"]["v_sz"]["scale_v_per_dps2"]
    with pytest.raises(ValidationError, match=r"scale_factor\.v_sz\.scale_v_per_dps2"):
        decided(raw)
