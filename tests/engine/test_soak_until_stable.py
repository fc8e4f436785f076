"""Soak until stable (issue 32 item 4): ``soak: {until_stable: {tolerance_c, window_s}, max_s}``
is planned, run on the twin's chamber to its known thermal lag, logged in the results, refused
where it cannot be done, and a fault when the chamber is not stable in time."""

from __future__ import annotations

import json
import math
from pathlib import Path

from typer.testing import CliRunner

from aatest.cli import app
from aatest.twin.model import ChamberModel

PROCEDURE = """\
procedure: soak-until-stable
sensor: {model: sr207, serial: "S1"}
rig: {turntable: sim, daq: sim, chamber: sim}
sampling: {rate_hz: 2000, samples: 4000, settle_s: 0.5}
steps:
  - temperature_steps:
      setpoints_c: [-20, 25, 60]
      soak: {until_stable: {tolerance_c: 0.05, window_s: 300}, max_s: MAX}
      off_wait_s: 10
      static: true
analysis: [sync, noise]
"""


def _write(tmp_path: Path, max_s: float = 7200, chamber: str = "sim") -> Path:
    path = tmp_path / "p.yaml"
    path.write_text(PROCEDURE.replace("MAX", f"{max_s:g}").replace("chamber: sim",
                                                                     f"chamber: {chamber}"))
    return path


def _records(tmp_path: Path) -> list[str]:
    return ["--records", f"sqlite:///{tmp_path / 'records.sqlite'}"]


def test_the_soak_ends_when_the_twins_sensor_is_stable_and_is_in_the_results(
        tmp_path: Path) -> None:
    result = CliRunner().invoke(app, ["run", str(_write(tmp_path)), "--out",
                                      str(tmp_path / "run"), "--no-progress", "--seed", "3",
                                      *_records(tmp_path)])
    assert result.exit_code in (0, 1), result.output
    doc = json.loads((tmp_path / "run" / "results.json").read_text())
    achieved = doc["metadata"]["soak_stability"]
    assert [a["setpoint_c"] for a in achieved] == [-20.0, 25.0, 60.0]
    # the twin's truth: the sensor follows T_set + ΔT0·exp(−t/τ) from the set-point command,
    # so the spread over [t − w, t] is |ΔT0|·e^(−(t−w)/τ)·(1 − e^(−w/τ)); solved for the tolerance
    model = ChamberModel()
    tau, window, tol = model.sensor_time_constant_s, 300.0, 0.05
    first = achieved[0]
    gap = abs(model.ambient_c - -20.0)  # the first soak starts from ambient
    expected_s = window + tau * math.log(gap * -math.expm1(-window / tau) / tol)
    # closed form against closed form: only floating-point rounding separates them
    assert math.isclose(first["waited_s"], expected_s, rel_tol=1e-9)
    for a in achieved:
        assert a["spread_c"] <= tol * (1 + 1e-9) and a["window_s"] == window
        assert abs(a["temperature_c"] - a["setpoint_c"]) < 0.1  # in band once stable


def test_not_stable_within_max_s_is_a_rig_fault(tmp_path: Path) -> None:
    # 42 °C to go with τ = 300 s: the spread over 300 s is 26 °C at 300 s, 0.05 °C only at 2182 s
    result = CliRunner().invoke(app, ["run", str(_write(tmp_path, max_s=600)), "--out",
                                      str(tmp_path / "run"), "--no-progress",
                                      *_records(tmp_path)])
    assert result.exit_code == 3, result.output
    assert "not stable within 600 s" in result.output


def test_validate_refuses_a_chamber_that_cannot_soak_until_stable(tmp_path: Path) -> None:
    result = CliRunner().invoke(app, ["validate", str(_write(tmp_path, chamber="espec")),
                                      *_records(tmp_path)])
    assert result.exit_code == 2, result.output
    assert "p.yaml:8:7: steps.0.temperature_steps.soak: chamber plugin 'espec' cannot soak " \
        "until stable" in result.output


def test_soak_s_and_soak_together_are_refused_at_the_step(tmp_path: Path) -> None:
    path = tmp_path / "p.yaml"
    both = "      off_wait_s: 10\n      soak_s: 60\n"
    path.write_text(_write(tmp_path).read_text().replace("      off_wait_s: 10\n", both))
    result = CliRunner().invoke(app, ["validate", str(path), *_records(tmp_path)])
    assert result.exit_code == 2, result.output
    assert "give soak_s (a fixed soak) or soak (until stable), not both" in result.output


def test_the_plan_counts_the_longest_soak(tmp_path: Path) -> None:
    result = CliRunner().invoke(app, ["plan", str(_write(tmp_path, max_s=3600)), "--json"])
    assert result.exit_code == 0, result.output
    chambers = [s for s in json.loads(result.output)["steps"] if s["kind"] == "chamber"]
    assert [(s["soak_max_s"], s["stable_tolerance_c"], s["stable_window_s"]) for s in chambers] \
        == [(3600.0, 0.05, 300.0)] * 3
