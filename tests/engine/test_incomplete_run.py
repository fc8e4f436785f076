"""A limit without a measured quantity: ``incomplete``, exit 1, on the certificate and in
results.json — never ``pass`` (issue 32, contracts §6 "Verdicts")."""

from __future__ import annotations

import json
import re
from pathlib import Path

from typer.testing import CliRunner

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


def test_a_limit_without_its_quantity_is_incomplete_and_exits_1(tmp_path: Path) -> None:
    procedure = tmp_path / "smoke.yaml"
    procedure.write_text(PROCEDURE, encoding="utf-8")
    done = RUNNER.invoke(app, ["run", str(procedure), "--out", str(tmp_path / "run"),
                               "--no-progress", "--seed", "3"])
    assert done.exit_code == 1, done.output
    assert INCOMPLETE.search(done.output), done.output
    results = json.loads((tmp_path / "run" / "results.json").read_text())
    assert results["overall"] == "incomplete"
    rows = {v["quantity"]: v for v in results["verdicts"]}
    assert rows["noise_rms_v"]["verdict"] == "pass"  # what was measured is still judged
    bias = rows["bias_deviation_v"]
    assert (bias["verdict"], bias["value"], bias["limit"], bias["limit_source"]) == (
        "not judged", None, 0.01, "procedure")
    assert "the analysis 'bias' does" in bias["reason"]
    certificate = (tmp_path / "run" / "report.html").read_text(encoding="utf-8")
    assert "The calibration is incomplete" in certificate
    assert "no listed analysis produces it (listed: sync, noise)" in certificate
    again = RUNNER.invoke(app, ["analyze", str(tmp_path / "run")])
    assert again.exit_code == 1 and INCOMPLETE.search(again.output), again.output
