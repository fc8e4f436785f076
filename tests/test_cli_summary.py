"""``aatest run``/``analyze`` end with a summary: in a log, on a terminal and as JSON.

The runs are real (the simulated rig, a two-step static procedure) in a subprocess without a
TTY, as CI or ``aatest run … | tee`` sees them.
"""

from __future__ import annotations

import io
import json
import os
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from rich.console import Console

from aatest.presentation.summary import summarise
from aatest.presentation.terminal import print_summary
from aatest.results import RunResults
from aatest.results.quantities import quantity
from aatest.results.rounding import measurement_text

PROCEDURE = Path(__file__).parent / "data" / "procedures" / "quick-static-2-steps.yaml"
STEP_LINE = re.compile(r"^\[(\d+)/(\d+)\] (s\d{3}\S*) .+ … done in \d+\.\d s")


def _aatest(*args: Any, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "aatest.cli", *map(str, args)],
                          capture_output=True, text=True, env=env, timeout=300, check=False)


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """One run with the tables, then ``analyze --json-summary`` of the same recording."""
    root = tmp_path_factory.mktemp("summary")
    env = {**os.environ, "AATEST_RECORDS": f"sqlite:///{root / 'records.db'}",
           "COLUMNS": "80", "TERM": "xterm-256color"}  # a narrow log must still not cut
    env.pop("AATEST_LAB", None)
    run = _aatest("run", PROCEDURE, "--out", root / "run", env=env)
    run_results = (root / "run" / "results.json").read_text()  # analyze renumbers it
    analyze = _aatest("analyze", root / "run", "--json-summary", env=env)
    return {"root": root, "run": run, "run_results": run_results, "analyze": analyze}


def test_run_without_a_tty_prints_one_full_line_per_step(runs: dict[str, Any]) -> None:
    run = runs["run"]
    assert run.returncode == 0, run.stdout + run.stderr
    lines = [line for line in run.stderr.splitlines() if line.startswith("[")]
    matches = [STEP_LINE.match(line) for line in lines]
    assert all(matches) and [m.group(1) for m in matches if m] == ["1", "2"]
    assert all(m.group(2) == "2" for m in matches if m)
    assert any(len(line) > 80 for line in lines), "lines are not cut at COLUMNS"
    assert "\x1b[" not in run.stdout + run.stderr  # no colour codes in a log


def test_run_summary_states_results_certificate_report_and_times(runs: dict[str, Any]) -> None:
    run, root = runs["run"], runs["root"]
    results = RunResults.model_validate_json(runs["run_results"])
    text = run.stdout
    for heading in ("Certified results", "Verdicts", "Overall verdict", "Certificate",
                    "Report", "Lab time", "Wall time"):
        assert heading in text
    bias = results.analysis.bias["v_sz"]  # type: ignore[index]
    q = quantity("bias")
    assert measurement_text(bias.bias_v, bias.expanded_uncertainty, q.unit, digits=q.digits) \
        in text and f"k = {bias.coverage_factor:g}" in text
    assert results.certificate_number and results.certificate_number in text
    assert str(root / "run" / "report.html") in text
    wall = re.search(r"Wall time\s+(\d+\.\d) s \(run; step loop (\d+\.\d) s\)", text)
    assert wall, text
    # the command's wall time includes the step loop, analysis, report and records
    assert float(wall.group(1)) > float(wall.group(2))
    assert all(len(line) <= 400 for line in text.splitlines())


def test_json_summary_matches_results_json(runs: dict[str, Any]) -> None:
    analyze, root = runs["analyze"], runs["root"]
    assert analyze.returncode == 0, analyze.stderr
    summary = json.loads(analyze.stdout)  # stdout is the JSON document and nothing else
    results = json.loads((root / "run" / "results.json").read_text())
    assert summary["command"] == "analyze" and summary["overall"] == results["overall"]
    assert summary["certificate_number"] == results["certificate_number"]
    assert summary["steps"] == len(results["steps"])
    assert summary["lab_duration_s"] == results["lab_duration_s"]
    assert summary["run_wall_duration_s"] == results["wall_duration_s"]
    assert summary["report_path"] == str(root / "run" / "report.html")
    judged = {(v["quantity"], v["channel"]): v for v in results["verdicts"]}
    assert {(v["quantity"], v["channel"]) for v in summary["verdicts"]} == set(judged)
    for row in summary["verdicts"]:
        stated = judged[(row["quantity"], row["channel"])]
        assert (row["value"], row["limit"], row["verdict"]) == (
            stated["value"], stated["limit"], stated["verdict"])
    bias = results["analysis"]["bias"]["v_sz"]
    row = next(r for r in summary["certified"] if r["quantity"] == "bias")
    assert (row["value"], row["expanded_uncertainty"], row["coverage_factor"]) == (
        bias["bias_v"], bias["expanded_uncertainty"], bias["coverage_factor"])


def test_forced_terminal_draws_the_tables(runs: dict[str, Any]) -> None:
    bundle = runs["root"] / "run"
    results = RunResults.model_validate_json((bundle / "results.json").read_text())
    summary = summarise(results, bundle, "run", 4.2)
    buffer = io.StringIO()
    print_summary(summary, Console(file=buffer, force_terminal=True, width=120))
    text = buffer.getvalue()
    assert "\x1b[" in text  # styled for a terminal
    plain = re.sub(r"\x1b\[[0-9;]*m", "", text)
    assert "─" in plain and "Wall time" in plain and "4.2 s (run" in plain
    assert summary.verdicts[0].name in plain and summary.overall in plain


@pytest.mark.parametrize(("steps", "said"), [(1, "(1 step)"), (2, "(2 steps)")])
def test_the_lab_time_counts_steps_in_words(steps: int, said: str) -> None:
    from rich.console import Console

    from aatest.presentation.summary import RunSummary
    from aatest.presentation.terminal import facts_table

    summary = RunSummary("run", "p", "sr207", "A1", [], [], "pass", None, "results.json", None,
                         steps, 75.0, 0.2, 2.9)
    console = Console(width=120, record=True)
    console.print(facts_table(summary))
    assert f"1 min 15 s {said}" in console.export_text()
