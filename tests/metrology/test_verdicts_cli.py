"""``aatest run``/``analyze`` on the twin exit 1 on a failed verdict, 0 otherwise, and the
certificate shows the engine's verdicts (docs/interfaces.md §1)."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import pytest
from ruamel.yaml import YAML
from typer.testing import CliRunner

from aatest.cli import app

SHIPPED = Path(__file__).resolve().parents[2] / "src/aatest/procedures/scale-factor.yaml"
RUNNER = CliRunner()


def _base() -> str:
    """The shipped procedure without its ``acceptance`` (and the comment above it)."""
    text = SHIPPED.read_text(encoding="utf-8")
    head, _sep, tail = text.partition("# one acceleration level")
    return head + tail[tail.index("acceptance:"):].split("\n", 1)[1]


def _procedure(tmp_path: Path, acceptance: str) -> Path:
    path = tmp_path / "scale-factor.yaml"
    path.write_text(_base() + acceptance, encoding="utf-8")
    return path


def _run(procedure: Path, out: Path) -> tuple[int, dict[str, Any]]:
    done = RUNNER.invoke(app, ["run", str(procedure), "--out", str(out), "--no-progress"])
    assert done.exception is None or isinstance(done.exception, SystemExit), done.output
    return done.exit_code, json.loads((out / "results.json").read_text())


def _scale_verdict(results: dict[str, Any]) -> dict[str, Any]:
    return next(v for v in results["verdicts"] if v["quantity"] == "scale_factor_deviation_pct")


@pytest.fixture(scope="module")
def default_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[int, Path, dict[str, Any]]:
    tmp = tmp_path_factory.mktemp("default")
    code, results = _run(SHIPPED, tmp / "run")
    return code, tmp / "run", results


def test_default_limits_pass_and_analyze_agrees(default_run: tuple[int, Path, Any]) -> None:
    code, run_dir, results = default_run
    assert code == 0 and results["overall"] == "pass"
    verdict = _scale_verdict(results)
    assert verdict["limit"] == 1.0 and verdict["rule"] == "simple"  # the sr207 datasheet
    entry = results["analysis"]["scale_factor"]["v_sz"]
    assert entry["expanded_uncertainty"] > 0 and entry["coverage_factor"] == 2.0
    # a reference term, a measuring-chain term, synchronisation and transverse motion
    assert {row["name"] for row in entry["budget"]} >= {
        "encoder_accuracy", "logger_gain", "clock", "wobble"}
    assert verdict["expanded_uncertainty"] == pytest.approx(
        100 * entry["expanded_uncertainty"] / 0.004014, rel=1e-9)
    again = RUNNER.invoke(app, ["analyze", str(run_dir)])
    assert again.exit_code == 0, again.output


def test_tight_limit_fails_run_analyze_and_certificate(tmp_path: Path) -> None:
    procedure = _procedure(tmp_path, "acceptance: {limits: {scale_factor_deviation_pct: 0.001}}\n")
    code, results = _run(procedure, tmp_path / "run")
    assert code == 1 and results["overall"] == "fail"
    assert _scale_verdict(results)["verdict"] == "fail"
    html = (tmp_path / "run" / "report.html").read_text()
    row = re.search(r"<td class=\"t\">Scale-factor deviation from nominal</td>.*?</tr>", html,
                    re.S)
    assert row and 'class="fail"' in row.group(0)
    assert (tmp_path / "run" / "results.json").is_file()  # written before the exit
    again = RUNNER.invoke(app, ["analyze", str(tmp_path / "run")])
    assert again.exit_code == 1 and "Scale-factor deviation from nominal" in again.output
    assert "scale_factor_deviation_pct" not in again.output  # the name, not the field


def test_guarded_value_within_u_is_conditional(tmp_path: Path,
                                               default_run: tuple[int, Path, Any]) -> None:
    """Limit = |value| + U/2: inside the limit but within its guard band."""
    verdict = _scale_verdict(default_run[2])
    limit = abs(verdict["value"]) + verdict["expanded_uncertainty"] / 2
    procedure = _procedure(tmp_path, "acceptance:\n  rule: guarded\n"
                                     "  judge: [scale_factor_deviation_pct]\n"
                                     f"  limits: {{scale_factor_deviation_pct: {limit!r}}}\n")
    code, results = _run(procedure, tmp_path / "run")
    guarded = _scale_verdict(results)
    assert guarded["value"] == pytest.approx(verdict["value"], abs=1e-12)
    assert guarded["verdict"] == "conditional-pass" and guarded["rule"] == "guarded"
    assert code == 0 and results["overall"] == "conditional-pass"


def test_unknown_limit_is_a_located_error(tmp_path: Path) -> None:
    procedure = _procedure(tmp_path, "acceptance:\n  limits: {scale_factor_deviaton_pct: 1}\n")
    done = RUNNER.invoke(app, ["run", str(procedure), "--out", str(tmp_path / "run")])
    assert done.exit_code == 2
    lines = len(_base().splitlines())
    where = f"{procedure}:{lines + 2}:12: acceptance.limits.scale_factor_deviaton_pct:"
    assert where in done.output


def test_imported_data_judged_by_its_dataset_datasheet(tmp_path: Path,
                                                      default_run: tuple[int, Path, Any]) -> None:
    """Without a procedure, the datasheet values in dataset.yaml are the limits."""
    data = tmp_path / "import"
    assert RUNNER.invoke(app, ["export", str(default_run[1]), "--csv", str(data)]).exit_code == 0
    yaml = YAML(typ="safe")
    manifest = yaml.load(data / "dataset.yaml")
    for sensor in manifest["sensors"]:
        sensor["scale_tolerance_pct"] = 0.001
    yaml.dump(manifest, data / "dataset.yaml")
    done = RUNNER.invoke(app, ["analyze", str(data)])
    assert done.exit_code == 1, done.output
    verdict = _scale_verdict(json.loads((data / "results.json").read_text()))
    assert verdict["limit"] == 0.001 and verdict["verdict"] == "fail"
