"""Each analysis states what it needs, and ``validate`` (and ``run``, before motion) checks it
at the analysis entry's or the step's FILE:LINE:COLUMN (issue 32)."""

from __future__ import annotations

import json
import re
from pathlib import Path

from typer.testing import CliRunner

from aatest.cli import app
from aatest.engine.analysis.coverage import requirements_markdown
from aatest.engine.requirements import PlanView, check_plan
from aatest.engine.steps import PlannedStep

RUNNER = CliRunner()
DOCS = Path(__file__).resolve().parents[2] / "docs" / "interfaces.md"

HEAD = """\
procedure: {name}
sensor: {{model: {model}, serial: "Q1"}}
rig: {{turntable: sim, daq: sim, chamber: {chamber}}}
sampling: {{rate_hz: 2000, samples: 4096, settle_s: 0.5}}
"""

#: a production smoke test, as a QA engineer wrote it: one static position, a bias limit
SMOKE = HEAD.format(name="smoke", model="sr207", chamber="none") + """\
steps:
  - static: {inner_deg: 0, outer_deg: 0}
analysis:
  - sync
  - bias
acceptance:
  limits: {bias_deviation_v: 0.01}
"""

#: cross-axis sensitivity of a single-axis sensor from outer-axis excitation
CROSS_AXIS = HEAD.format(name="cross-axis", model="sr207", chamber="none") + """\
steps:
  - sine: {axis: outer, frequency_hz: 1.0, accel_dps2: 100}
  - sine: {axis: outer, frequency_hz: 1.0, accel_dps2: 100, inner_deg: 90}
analysis: [sync, misalignment]
"""

#: set-points without a chamber in the rig
NO_CHAMBER = HEAD.format(name="temperature", model="sr207", chamber="none") + """\
steps:
  - temperature_steps:
      setpoints_c: [-20, 25, 60]
      soak_s: 10
      off_wait_s: 1
analysis: [sync, temperature]
"""


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "procedure.yaml"
    path.write_text(text, encoding="utf-8")
    return path


def _located(output: str, path: Path) -> tuple[int, int, str]:
    match = re.search(rf"{re.escape(str(path))}:(\d+):(\d+): ([^:]+): (.*)", output)
    assert match, output
    return int(match[1]), int(match[2]), match[3] + ": " + match[4]


def test_docs_table_is_generated_from_the_declarations() -> None:
    text = DOCS.read_text(encoding="utf-8")
    block = text.split("<!-- requirements:begin -->\n")[1].split("<!-- requirements:end -->")[0]
    assert block == requirements_markdown()


def test_smoke_test_with_one_position_is_refused_at_the_bias_entry(tmp_path: Path) -> None:
    """One static position has no ±1 g pair: refused at ``- bias`` (line 9, column 5), and
    ``run`` refuses it too before anything is recorded."""
    path = _write(tmp_path, SMOKE)
    done = RUNNER.invoke(app, ["validate", str(path)])
    assert done.exit_code == 2
    line, col, message = _located(done.output, path)
    assert (line, col) == (9, 5)
    assert message.startswith("analysis.1: analysis 'bias' needs static positions")
    assert "±1 g pair" in message and "none for channel(s) v_sz" in message
    run = RUNNER.invoke(app, ["run", str(path), "--out", str(tmp_path / "run"), "--no-progress"])
    assert run.exit_code == 2 and not (tmp_path / "run" / "recording.mcap").exists()


def test_cross_axis_of_a_single_axis_sensor_is_refused_with_the_reason(tmp_path: Path) -> None:
    path = _write(tmp_path, CROSS_AXIS)
    done = RUNNER.invoke(app, ["validate", str(path)])
    assert done.exit_code == 2
    line, col, message = _located(done.output, path)
    assert (line, col) == (8, 18)  # the `misalignment` entry of `analysis: [sync, misalignment]`
    assert "three-sensor unit" in message and "single-axis sensor" in message
    assert "sine steps of a misalignment scenario" in done.output


def test_set_points_without_a_chamber_are_refused_at_the_step(tmp_path: Path) -> None:
    path = _write(tmp_path, NO_CHAMBER)
    done = RUNNER.invoke(app, ["validate", str(path)])
    assert done.exit_code == 2
    line, _col, message = _located(done.output, path)
    assert line == 6 and message.startswith("steps.0.temperature_steps: analysis 'temperature'")
    assert "needs a chamber plugin" in message
    # (static records only: the bias coefficient is what this plan can give)
    ok = RUNNER.invoke(app, ["validate", str(_write(tmp_path, NO_CHAMBER.replace(
        "chamber: none", "chamber: sim") + "acceptance: {judge: [bias_temperature_v_per_c]}\n"))])
    assert ok.exit_code == 0, ok.output
    assert "3 steps (+ 3 chamber set-point changes)" in ok.output


def test_validate_prints_the_steps_each_analysis_uses(tmp_path: Path) -> None:
    text = SMOKE.replace("  - static: {inner_deg: 0, outer_deg: 0}\n",
                         "  - static: {inner_deg: 0, outer_deg: 0}\n"
                         "  - static: {inner_deg: 0, outer_deg: 180}\n"
                         "  - sine: {axis: inner, frequency_hz: 1.0, accel_dps2: 100}\n")
    done = RUNNER.invoke(app, ["validate", str(_write(tmp_path, text))])
    assert done.exit_code == 0, done.output
    lines = done.output.splitlines()
    assert "analyses and the steps each will use:" in lines
    bias = next(line for line in lines if line.startswith("  bias: "))
    assert bias == "  bias: s001-static-i0-o0, s002-static-i0-o180"


def test_an_analysis_without_a_declaration_is_not_checked() -> None:
    class Vendor:
        key = "vendor"

    steps = (PlannedStep(id="s001", kind="static"),)
    coverage = check_plan({"vendor": Vendor}, PlanView(steps, "none", {"v_sz": "I"}))
    assert coverage.unmet == [] and "vendor" not in coverage.uses


def _slow(rate: int, samples: int, analysis: str) -> str:
    """A 1 Hz scale-factor sine logged at ``rate`` Hz, with the analyses ``analysis``."""
    return HEAD.format(name="slow", model="sr207", chamber="none").replace(
        "rate_hz: 2000, samples: 4096", f"rate_hz: {rate}, samples: {samples}") + f"""\
steps:
  - sine: {{axis: inner, frequency_hz: 1.0, accel_dps2: 400, snap: coherent}}
analysis: [{analysis}]
"""


def test_a_log_too_slow_for_the_freeze_pulse_is_refused_before_anything_moves(
        tmp_path: Path) -> None:
    """At 100 Hz the run used to record, then stop with "sync edges missing — check the
    freeze-pulse wiring" (exit 3): the wiring was fine, the rate was not. ``sync`` is held to
    it when a listed analysis requires it, too."""
    listed = _write(tmp_path, _slow(100, 400, "sync, scale_factor"))
    done = RUNNER.invoke(app, ["validate", str(listed)])
    assert done.exit_code == 2, done.output
    line, col, message = _located(done.output, listed)
    assert (line, col) == (6, 5)  # at the step
    assert message.startswith("steps.0.sine: analysis 'sync' needs every recorded step logged "
                              "at ≥ 200 Hz"), message
    assert "is logged at 100 Hz" in message
    required = _write(tmp_path, _slow(100, 400, "scale_factor"))
    done = RUNNER.invoke(app, ["validate", str(required)])
    assert done.exit_code == 2, done.output
    assert "analysis 'sync' (which 'scale_factor' requires) needs" in done.output
    run = RUNNER.invoke(app, ["run", str(required), "--out", str(tmp_path / "run"),
                              "--no-progress"])
    assert run.exit_code == 2 and not (tmp_path / "run" / "recording.mcap").exists()
    fast = _write(tmp_path, _slow(200, 800, "sync, scale_factor"))
    assert RUNNER.invoke(app, ["validate", str(fast)]).exit_code == 0


def test_a_drift_record_is_not_held_to_the_freeze_pulse(tmp_path: Path) -> None:
    """``drift`` reads the DAQ's log alone: a slow drift record runs (the twin folds the
    floor's rocking below the log's Nyquist frequency), and no step is checked for sync."""
    path = _write(tmp_path, HEAD.format(name="drift", model="sr207", chamber="none").replace(
        "rate_hz: 2000, samples: 4096", "rate_hz: 50, samples: 3000") + """\
steps:
  - static: {inner_deg: 0, outer_deg: 0}
analysis: [drift]
""")
    done = RUNNER.invoke(app, ["run", str(path), "--out", str(tmp_path / "run"),
                               "--no-progress", "--seed", "2"])
    assert done.exit_code == 0, done.output
    results = json.loads((tmp_path / "run" / "results.json").read_text(encoding="utf-8"))
    assert results["steps"][0]["sample_rate_hz"] == 50
    assert "drift" in results["analysis"] and not results["analysis_errors"]
