"""Several effects at once, and effects outside the vocabulary (issue 15).

Datasets come from :mod:`multi_cases`: two or three simultaneous effects written from the
sensor physics (no aatest simulation code) or by the twin (table effects, cross-axis,
g-sensitivity), out-of-vocabulary effects alone and beside a vocabulary effect, and clean
data, all exported in the import format and diagnosed through the CLI as a user would.

Scoring (issue 15 "Done when"): a multi-effect case is correct when every true effect is
named with every parameter within 25 % and nothing else is named; an out-of-vocabulary case
names no wrong vocabulary effect (its vocabulary effects, if any, named correctly) and
reports its structure in ``unexplained`` with a gain; clean data gives empty ``findings``
and ``unexplained`` and exit 0. The default run diagnoses two look-alike cases on short
records; the full suite (≥ 30 multi-effect, ≥ 10 out-of-vocabulary, 3 clean) is slow.
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from multi_cases import Case, diagnose, score, suite, write

#: samples per step (2^12: the 2-core machine is shared; the issue measured 2^14)
QUICK_SAMPLES = 4096
SUITE_SAMPLES = 4096
#: the issue's counts: cases with several (≥ 2) effects, and how many of each kind
SEVERAL = 2
MIN_MULTI = 30
MIN_OOV = 10
QUICK = ("physics-time_delay+sensor_dynamics", "physics-nonlinearity_cubic+hysteresis")


def _case(name: str) -> Case:
    return next(c for c in suite() if c.name == name)


@pytest.mark.parametrize("name", QUICK, ids=QUICK)
def test_look_alikes_are_separated_and_refitted_jointly(tmp_path: Path, name: str) -> None:
    """A delay beside sensor dynamics, a cubic beside hysteresis: both named, within 25 %."""
    case = _case(name)
    code, doc = diagnose(write(case, tmp_path / "data", QUICK_SAMPLES))
    naming, _ = score(case, code, doc)
    assert naming == []
    assert code == 1
    for finding in doc["findings"]:  # each carries its own marginal gain in the joint model
        marginal = finding["marginal"]
        assert marginal["delta_bic"] < -10
        assert marginal["rmse_v_without"] > marginal["rmse_v_with"]


def test_suite_covers_the_vocabulary_and_the_hard_pairs() -> None:
    """Every vocabulary effect 2–3 times, ≥ 30 multi-effect and ≥ 10 OOV cases."""
    from aatest.diagnose.scenarios import DRAWS

    cases = suite()
    multi = [c for c in cases if len(c.effects) >= SEVERAL and not c.oov]
    counts = {e: sum(any(x.effect == e for x in c.effects) for c in multi) for e in DRAWS}
    assert len(multi) >= MIN_MULTI
    assert sum(c.oov for c in cases) >= MIN_OOV
    assert all(n >= SEVERAL for n in counts.values()), counts
    pairs = [{"time_delay", "sensor_dynamics"}, {"nonlinearity_cubic", "hysteresis"},
             {"bias_temperature", "scale_temperature"}, {"clock_drift", "jerk_sensitivity"},
             {"rate_ripple", "motor_vibration", "excess_noise"},
             {"saturation", "cross_axis", "excess_noise"}]
    for pair in pairs:
        assert any(pair <= {e.effect for e in c.effects} for c in multi), pair


@pytest.mark.slow
def test_multi_effect_and_out_of_vocabulary_suite(tmp_path_factory: pytest.TempPathFactory
                                                  ) -> None:
    """Scores printed for the closing note; targets: multi ≥ 80 %, OOV ≥ 80 % / ≥ 80 %."""
    cases = suite()
    results: dict[str, tuple[list[str], list[str]]] = {}
    start = time.perf_counter()
    for case in cases:
        data = write(case, tmp_path_factory.mktemp(case.name) / "data", SUITE_SAMPLES)
        results[case.name] = score(case, *diagnose(data))
    multi = [c.name for c in cases if c.effects and not c.oov]
    oov = [c.name for c in cases if c.oov]
    clean = [c.name for c in cases if not c.effects]
    multi_ok = sum(not results[n][0] for n in multi)
    oov_named = sum(not results[n][0] for n in oov)
    oov_unexplained = sum(not results[n][1] for n in oov)
    clean_ok = sum(not results[n][0] for n in clean)
    print(f"\nmulti-effect: {multi_ok}/{len(multi)} fully correct; out-of-vocabulary: "
          f"{oov_named}/{len(oov)} no wrong name, {oov_unexplained}/{len(oov)} reported in "
          f"unexplained; clean: {clean_ok}/{len(clean)} ({time.perf_counter() - start:.0f} s)")
    for name, (naming, unexplained) in results.items():
        if naming or unexplained:
            print(f"  {name}: {'; '.join(naming + unexplained)}")
    assert clean_ok == len(clean)
    assert multi_ok >= 0.8 * len(multi)
    assert oov_named >= 0.8 * len(oov)
    assert oov_unexplained >= 0.8 * len(oov)
