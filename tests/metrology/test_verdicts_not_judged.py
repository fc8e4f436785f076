"""Not measured is never passed (contracts §6 "Verdicts"): an asked quantity without a value
is ``not judged`` with its reason, the overall verdict ``incomplete`` and the run fails."""

from __future__ import annotations

import copy

import pytest
from contract_results import CHANNELS, decided, make_results

from aatest.engine.analysis.plugins import installed_analyses, listed_analyses
from aatest.engine.interfaces import SensorDatasheet
from aatest.engine.procedure.models import Acceptance
from aatest.metrology.uncertainty import apply_uncertainty
from aatest.metrology.verdicts import apply_verdicts, failed, overall
from aatest.results import RunResults
from aatest.results.base import Verdict


def _without(*keys: str) -> RunResults:
    raw = make_results()
    for key in keys:
        del raw["analysis"][key]
    return RunResults.model_validate(raw)


def _judged(results: RunResults, acceptance: Acceptance, listed: list[str]) -> RunResults:
    apply_uncertainty(results)
    sheets = {ch: SensorDatasheet(model="sr207-aamu") for ch in CHANNELS}
    return apply_verdicts(results, sheets, acceptance, listed_analyses(listed),
                          installed_analyses())


def test_a_procedure_limit_without_its_quantity_is_incomplete() -> None:
    """The bias limit of the procedure with no bias result: one ``not judged`` per channel,
    naming the limit's source; the run is ``incomplete`` and fails (exit 1)."""
    acceptance = Acceptance.model_validate({"limits": {"bias_deviation_v": 0.01}})
    results = decided(_without("bias", "misalignment"), acceptance)
    missing = [v for v in results.verdicts if v.verdict == "not judged"]
    assert [(v.quantity, v.channel) for v in missing] == [
        ("bias_deviation_v", ch) for ch in CHANNELS]
    assert all(v.value is None and v.limit == 0.01 and v.limit_source == "procedure"
               for v in missing)
    assert all("no listed analysis produces it" in v.reason for v in missing)
    assert results.overall == "incomplete" and failed(results)


def test_a_listed_analysis_that_produced_nothing_says_what_it_needs() -> None:
    """``bias`` listed and skipped: its quantities are not judged (datasheet limits) with the
    analysis' declared needs as the reason."""
    results = _without("bias", "misalignment")
    results.analysis_skipped = ["bias"]
    judged = _judged(results, Acceptance(), ["sync", "bias"])
    missing = {(v.quantity, v.channel): v for v in judged.verdicts if v.verdict == "not judged"}
    assert set(missing) == {(q, ch) for q in ("bias_deviation_v", "g_sensitivity_dps2_per_g")
                            for ch in CHANNELS}
    reason = missing[("bias_deviation_v", "v_sz")].reason
    assert "analysis 'bias' does not apply" in reason and "±1 g pair" in reason
    assert missing[("bias_deviation_v", "v_sz")].limit_source == "datasheet"
    assert judged.overall == "incomplete"


def test_a_listed_analysis_without_quantities_is_named_when_it_did_not_apply() -> None:
    results = _without("misalignment")
    results.analysis_skipped = ["frf"]
    judged = _judged(results, Acceptance(), ["sync", "frf"])
    row = next(v for v in judged.verdicts if v.verdict == "not judged")
    assert (row.quantity, row.channel, row.limit) == ("frf", "all", None)
    assert "'frf' is listed but does not apply" in row.reason and "a sine step" in row.reason


def test_judge_chooses_the_judged_quantities() -> None:
    """``acceptance.judge`` keeps only the chosen quantities; one not produced is not judged."""
    acceptance = Acceptance.model_validate(
        {"judge": ["scale_factor_deviation_pct", "misalignment_deg"]})
    judged = decided(_without("misalignment"), acceptance)
    assert {v.quantity for v in judged.verdicts} == {"scale_factor_deviation_pct",
                                                    "misalignment_deg"}
    row = next(v for v in judged.verdicts if v.quantity == "misalignment_deg")
    assert (row.verdict, row.channel) == ("not judged", "all") and judged.overall == "incomplete"


def test_a_failure_outranks_incomplete() -> None:
    def verdict(value: str) -> Verdict:
        return Verdict(quantity="bias_deviation_v", channel="v_sz", value=None, limit=1.0,
                       rule="simple", verdict=value)  # type: ignore[arg-type]

    assert overall([verdict("pass"), verdict("not judged")]) == "incomplete"
    assert overall([verdict("fail"), verdict("not judged")]) == "fail"
    assert overall([verdict("not judged")]) == "incomplete"


def test_the_default_run_keeps_its_verdicts() -> None:
    """Without a limit in the procedure and with every analysis' result present, nothing is
    added: the verdicts are the ones the results contain, each naming the datasheet."""
    raw = make_results()
    judged = decided(copy.deepcopy(raw))
    assert judged.verdicts and all(v.verdict != "not judged" for v in judged.verdicts)
    assert {v.limit_source for v in judged.verdicts} == {"datasheet"}


@pytest.mark.parametrize("order", [1, 3])
def test_one_level_does_not_pass_a_nonlinearity_limit(order: int) -> None:
    """Issue 32: a straight line chosen on one level has a non-linearity of 0 by construction
    (4.8e-15 % passed a 0.1 % limit); asked for by the procedure, it is not judged."""
    raw = make_results()
    del raw["analysis"]["misalignment"]
    for entry in raw["analysis"]["scale_factor"].values():
        # a straight line, or a cubic the data chose: its deviation from itself is rounding
        entry["order"], entry["nonlinearity_pct_fr"] = order, 4.8e-15
    acceptance = Acceptance.model_validate({"limits": {"nonlinearity_pct_fr": 0.1}})
    judged = _judged(RunResults.model_validate(raw), acceptance, ["sync", "scale_factor"])
    rows = [v for v in judged.verdicts if v.quantity == "nonlinearity_pct_fr"]
    assert rows and all(v.verdict == "not judged" and v.value is None for v in rows)
    assert "one acceleration level" in rows[0].reason and judged.overall == "incomplete"
    assert failed(judged)
