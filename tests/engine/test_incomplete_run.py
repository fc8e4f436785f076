"""A limit without a measured quantity: ``incomplete``, exit 1, on the certificate and in
results.json — never ``pass`` (issue 32, contracts §6 "Verdicts"). A quantity no listed
analysis can produce is known from the procedure alone: refused before anything moves."""

from __future__ import annotations

import json
import re
from pathlib import Path

from typer.testing import CliRunner, Result

from aatest.cli import app

#: the closing summary's line, as a table row or as text
INCOMPLETE = re.compile(r"overall verdict:?\s+incomplete", re.IGNORECASE)

RUNNER = CliRunner()

#: one static position, no bias analysis: the procedure's bias limit cannot be judged
PROCEDURE = """\
procedure: smoke-bias-limit
sensor: {model: sr207, serial: "S1"}
sampling: {rate_hz: 2000, samples: 4096, settle_s: 0.5}
steps:
  - static: {inner_deg: 0, outer_deg: 0}
analysis: [sync, noise]
acceptance:
  limits: {bias_deviation_v: 0.01, noise_rms_v: 0.5}
"""

#: one acceleration level: the scale factor is measured, its non-linearity is not resolved
ONE_LEVEL = """\
procedure: one-level-linearity
sensor: {model: sr207, serial: "S1"}
sampling: {rate_hz: 2000, samples: 8000, settle_s: 0.5}
steps:
  - sine: {axis: inner, frequency_hz: 1.0, accel_dps2: 400, snap: coherent}
analysis: [sync, reference, scale_factor]
acceptance: {judge: [scale_factor_deviation_pct, nonlinearity_pct_fr]}
"""


def _refused(procedure: Path, text: str) -> tuple[Path, Result]:
    """``text`` written to ``procedure`` and validated: refused (exit 2)."""
    procedure.write_text(text, encoding="utf-8")
    checked = RUNNER.invoke(app, ["validate", str(procedure)])
    assert checked.exit_code == 2, checked.output
    return procedure, checked


def test_a_limit_no_listed_analysis_produces_is_refused_before_anything_moves(
        tmp_path: Path) -> None:
    procedure, checked = _refused(tmp_path / "smoke.yaml", PROCEDURE)
    # at the limit (line 8, column 12), naming what is listed and what would produce it
    assert f"{procedure}:8:12: acceptance.limits.bias_deviation_v: " in checked.output
    assert "no listed analysis produces it (listed: sync, noise); the analysis 'bias' " \
           "does" in checked.output
    assert "noise_rms_v" not in checked.output  # the noise analysis is listed: it is produced
    done = RUNNER.invoke(app, ["run", str(procedure), "--out", str(tmp_path / "run"),
                               "--no-progress", "--seed", "3"])
    assert done.exit_code == 2, done.output
    assert "acceptance.limits.bias_deviation_v" in done.output
    assert not (tmp_path / "run" / "recording.mcap").exists()
    judged = procedure.read_text(encoding="utf-8").replace(
        "  limits:", "  judge: [noise_rms_v, bias_deviation_v]\n  limits:")
    procedure.write_text(judged, encoding="utf-8")
    listed = RUNNER.invoke(app, ["validate", str(procedure)])
    assert listed.exit_code == 2, listed.output
    assert f"{procedure}:8:24: acceptance.judge.1: acceptance.judge asks for " \
           "bias_deviation_v" in listed.output
    asked_less = judged.replace("[noise_rms_v, bias_deviation_v]", "[noise_rms_v]")
    procedure.write_text(asked_less, encoding="utf-8")
    accepted = RUNNER.invoke(app, ["validate", str(procedure)])
    assert accepted.exit_code == 0, accepted.output


def test_a_quantity_the_data_do_not_give_is_incomplete_and_exits_1(tmp_path: Path) -> None:
    procedure = tmp_path / "one-level.yaml"
    procedure.write_text(ONE_LEVEL, encoding="utf-8")
    done = RUNNER.invoke(app, ["run", str(procedure), "--out", str(tmp_path / "run"),
                               "--no-progress", "--seed", "3"])
    assert done.exit_code == 1, done.output
    assert INCOMPLETE.search(done.output), done.output
    results = json.loads((tmp_path / "run" / "results.json").read_text())
    assert results["overall"] == "incomplete"
    rows = {v["quantity"]: v for v in results["verdicts"]}
    assert rows["scale_factor_deviation_pct"]["verdict"] == "pass"  # measured: still judged
    linearity = rows["nonlinearity_pct_fr"]
    assert (linearity["verdict"], linearity["value"], linearity["limit_source"]) == (
        "not judged", None, "datasheet")
    assert "one acceleration level: no non-linearity is resolved" in linearity["reason"]
    certificate = (tmp_path / "run" / "report.html").read_text(encoding="utf-8")
    assert "The calibration is incomplete" in certificate
    assert "one acceleration level: no non-linearity is resolved" in certificate
    again = RUNNER.invoke(app, ["analyze", str(tmp_path / "run")])
    assert again.exit_code == 1 and INCOMPLETE.search(again.output), again.output


#: set-points with static records only: the scale-factor coefficient needs sine records
STATIC_ONLY = """\
procedure: static-only-campaign
sensor: {model: sr207, serial: "T1"}
rig: {turntable: sim, daq: sim, chamber: sim}
sampling: {rate_hz: 2000, samples: 4096, settle_s: 0.5}
steps:
  - temperature_steps: {setpoints_c: [22, 40, -30], soak_s: 10, static: true}
analysis: [sync, temperature]
"""


def test_a_coefficient_the_plan_cannot_give_is_refused_at_its_analysis(tmp_path: Path) -> None:
    """Judged by default (no acceptance.judge), the scale coefficient of a campaign without
    sine records used to end the run incomplete after every soak: refused at the analysis
    entry; judging only the bias coefficient runs."""
    procedure, checked = _refused(tmp_path / "campaign.yaml", STATIC_ONLY)
    assert f"{procedure}:7:18: analysis.1: scale_temperature_per_c is judged" in checked.output
    assert "produces it only from sine records of one frequency and acceleration at ≥ 3 " \
           "chamber set-points spanning ≥ 5 °C: the plan has none" in checked.output
    assert "bias_temperature_v_per_c" not in checked.output  # static at 3 set-points: given
    procedure.write_text(STATIC_ONLY + "acceptance: {judge: [bias_temperature_v_per_c]}\n",
                         encoding="utf-8")
    assert RUNNER.invoke(app, ["validate", str(procedure)]).exit_code == 0
