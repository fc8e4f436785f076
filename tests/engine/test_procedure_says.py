"""What the procedure asks is what the tool says (issue 32 items 4-5): validate names the
snapped frequency, validate and run count the same steps, and the certificate says whether
each limit came from the procedure or the datasheet."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

from aatest.cli import app
from aatest.plugins.report.certificate import _conformity
from aatest.results import RunResults
from aatest.results.base import Verdict

TEMPERATURE = """\
procedure: counted
sensor: {model: sr207, serial: "C1"}
rig: {turntable: sim, daq: sim, chamber: sim}
sampling: {rate_hz: 2000, samples: 4000, settle_s: 0.5}
steps:
  - temperature_steps:
      setpoints_c: [-20, 25, 60]
      soak_s: 60
      off_wait_s: 5
      static: true
      dynamic: {axis: inner, frequency_hz: 1.0, accel_dps2: 400}
analysis: [sync, scale_factor]
"""


def _records(tmp_path: Path) -> list[str]:
    return ["--records", f"sqlite:///{tmp_path / 'records.sqlite'}"]


def test_validate_names_the_snapped_frequency(tmp_path: Path) -> None:
    path = tmp_path / "p.yaml"
    # 1.03 Hz in 4000 samples at 2000 Hz: 2.06 cycles → 2 whole cycles, f = 2·2000/4000 = 1 Hz
    path.write_text(TEMPERATURE.replace("frequency_hz: 1.0", "frequency_hz: 1.03"))
    result = CliRunner().invoke(app, ["validate", str(path), *_records(tmp_path)])
    assert result.exit_code == 0, result.output
    assert "snapped: s003-sine-inner-1.0000Hz-400dps2-m20C: 1.03 Hz → 1 Hz" in result.output


def test_validate_and_run_count_the_same_steps(tmp_path: Path) -> None:
    path = tmp_path / "p.yaml"
    path.write_text(TEMPERATURE)
    checked = CliRunner().invoke(app, ["validate", str(path), *_records(tmp_path)])
    assert checked.exit_code == 0, checked.output
    said = re.search(r"OK — (\d+) steps \(\+ (\d+) chamber set-point changes\)", checked.output)
    assert said and (int(said[1]), int(said[2])) == (6, 3), checked.output
    ran = CliRunner().invoke(app, ["run", str(path), "--out", str(tmp_path / "run"),
                                   "--no-progress", *_records(tmp_path)])
    assert ran.exit_code in (0, 1), ran.output
    counted = re.search(r"Lab time .*\((\d+) steps\)", ran.output)
    assert counted and int(counted[1]) == int(said[1]), ran.output


def _verdict(source: str) -> Verdict:
    return Verdict(quantity="bias_deviation_v", channel="v_sz", value=0.001, limit=0.01,
                   rule="simple", verdict="pass", unit="V", limit_source=source)


@pytest.mark.parametrize(("sources", "said"), [
    (["procedure"], "Conformity with the procedure's acceptance limits,"),
    (["datasheet"], "Conformity with the sensor's datasheet limits,"),
    (["procedure", "datasheet"], "Conformity with the procedure's acceptance limits and, where "
                                 "it sets none, the sensor's datasheet limits"),
])
def test_the_certificate_says_where_the_limits_came_from(sources: list[str], said: str) -> None:
    results = RunResults(procedure="p", verdicts=[_verdict(s) for s in sources])
    assert _conformity(results, "simple").startswith(said)


def test_schema_install_writes_what_the_modeline_names(tmp_path: Path) -> None:
    from aatest.schemas.export import render

    result = CliRunner().invoke(app, ["schema", "--install", str(tmp_path / "schemas")])
    assert result.exit_code == 0, result.output
    installed = tmp_path / "schemas" / "procedure.schema.json"
    assert installed.read_text(encoding="utf-8") == render()
    assert (tmp_path / "schemas" / "results.schema.json").read_text(encoding="utf-8") == \
        render(results=True)
    assert f"# yaml-language-server: $schema={installed}" in result.output
