"""A run through the simulator servers (Modbus table, CAN logger) is a simulation: the drivers
read the servers' identification at start, and the run is numbered ``SIM-…``, titled as a
simulation and kept out of the unit's history. The same servers posing as hardware take the
real-rig path: an unnamed unit is refused before any motion, a named one is calibrated."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import pytest
from served_rig import ServedRig, served_rig
from typer.testing import CliRunner

from aatest.cli import app
from aatest.engine.simulation import SIMULATION_TITLE
from aatest.protocols.modbus_map import Command

SEED = 5
PROCEDURE = """\
procedure: served
sensor: {model: sr207}
sampling: {rate_hz: 2000, samples: 8000, settle_s: 1}
steps:
  - sine: {axis: inner, frequency_hz: 1.0, accel_dps2: 400, snap: coherent}
analysis: [sync, reference, scale_factor]
report: {template: calibration-certificate, sign: false}
"""
#: commands that move the table or record (MOTOR_ON belongs to the driver's start, which is
#: where it learns whether a simulator answers; the motor is switched off again at once)
MOTION = {Command.START_MOTION, Command.ARM_LOG}


@pytest.fixture
def served(rig_entry_points: None, tmp_path: Path,
           monkeypatch: pytest.MonkeyPatch) -> Iterator[ServedRig]:
    """The twin behind Modbus and CAN on loopback, counting every command the table executes."""
    with served_rig(tmp_path, monkeypatch, SEED, f"mark-{tmp_path.name}") as rig:
        (tmp_path / "p.yaml").write_text(PROCEDURE)
        yield rig


def _run(tmp_path: Path, served: ServedRig, url: str, *extra: str) -> tuple[int, str]:
    result = CliRunner().invoke(app, [
        "run", str(tmp_path / "p.yaml"), "--rig", str(served.rig), "--out", str(tmp_path / "r"),
        "--seed", str(SEED), "--no-progress", "--records", url, *extra])
    return result.exit_code, result.output


def test_a_run_on_the_simulator_servers_is_a_simulation(served: ServedRig, tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'records.sqlite'}"
    code, output = _run(tmp_path, served, url, "--serial", "SN-77")
    assert code == 0, output
    results = json.loads((tmp_path / "r" / "results.json").read_text())
    assert results["metadata"]["simulated_parts"] == ["daq:can", "turntable:modbus"]
    assert results["metadata"]["kind"] == "simulation"
    assert results["certificate_number"].startswith("SIM-")
    report = (tmp_path / "r" / "report.html").read_text()
    assert f"<h1>{SIMULATION_TITLE}</h1>" in report and 'id="simulation-mark"' in report
    history = CliRunner().invoke(app, ["history", "SN-77", "--records", url])
    assert history.exit_code == 2 and "1 simulation(s)" in history.output
    listed = CliRunner().invoke(app, ["history", "SN-77", "--records", url, "--json",
                                      "--include-simulations"])
    assert json.loads(listed.stdout)["records"][0]["kind"] == "simulation"


def test_an_unnamed_unit_on_a_real_rig_is_refused_before_motion(
        served: ServedRig, tmp_path: Path) -> None:
    served.server.controller.pose_as_hardware("ACME TC-2 controller")
    served.logger.simulated = False
    url = f"sqlite:///{tmp_path / 'records.sqlite'}"
    code, output = _run(tmp_path, served, url)
    assert code == 2, output
    assert "no unit serial" in output and "--serial" in output
    assert not MOTION & set(served.commands), served.commands  # the table never moved
    assert Command.EMERGENCY_STOP in served.commands  # and was left safe


def test_a_named_unit_on_a_real_rig_is_calibrated(
        served: ServedRig, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    served.server.controller.pose_as_hardware("ACME TC-2 controller")
    served.logger.simulated = False
    monkeypatch.setenv("AATEST_SERIAL", "SN-1001")
    url = f"sqlite:///{tmp_path / 'records.sqlite'}"
    code, output = _run(tmp_path, served, url)
    assert code == 0, output
    results = json.loads((tmp_path / "r" / "results.json").read_text())
    assert results["metadata"]["simulated_parts"] == []
    assert results["metadata"]["kind"] == "calibration"
    assert results["metadata"]["sensor"]["serial"] == "SN-1001"
    assert results["certificate_number"].startswith("LAB-")
    report = (tmp_path / "r" / "report.html").read_text()
    assert "<h1>Calibration certificate</h1>" in report
    assert 'id="simulation-mark"' not in report and "Simulation report" not in report
    assert 'id="item-serial">SN-1001<' in report
    history = CliRunner().invoke(app, ["history", "SN-1001", "--records", url, "--json"])
    assert history.exit_code == 0, history.output
    (record,) = json.loads(history.stdout)["records"]
    assert record["kind"] == "calibration"
    assert record["certificate_number"] == results["certificate_number"]
