"""The station starts a run only after the checks ``aatest run`` makes before anything moves.

Before, the station called the run directly: a plan the preflight refuses (here a three-axis
unit through a twin whose model file holds one sensor) recorded every step and then ended in
an internal error, and a rig naming an overdue reference standard ran anyway, its certificate
naming no reference. Now a start either passes both checks or is answered with the problems,
and no run directory, rig or step exists.
"""

from __future__ import annotations

import json
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest
from one_sensor_twin import one_sensor_twin
from run_events import Events
from typer.testing import CliRunner

from aatest.cli import app
from aatest.engine.errors import EXIT_BAD_INPUT, AatestError
from aatest.engine.run.session import UnitName
from aatest.station.catalogue import Procedures, RunsDirHistory
from aatest.station.control import RunController

QUICK = Path(__file__).parent / "data" / "quick-scale-factor.yaml"
TODAY = datetime.now(UTC).date()


def _controller(tmp_path: Path, rig: Path, procedure: str) -> tuple[RunController, Events]:
    lab = tmp_path / "lab"
    lab.mkdir(exist_ok=True)
    (lab / "p.yaml").write_text(procedure, encoding="utf-8")
    (tmp_path / "runs").mkdir(exist_ok=True)
    events = Events()
    return RunController(Procedures(lab), RunsDirHistory(tmp_path / "runs"), rig, events,
                         records_url=f"sqlite:///{tmp_path / 'records.sqlite'}"), events


def _refused(controller: RunController, events: Events, tmp_path: Path, says: str) -> None:
    with pytest.raises(AatestError) as refused:
        controller.start("lab/p.yaml", "Ada Operator", UnitName("SN-1"))
    assert refused.value.exit_code == EXIT_BAD_INPUT
    assert says in str(refused.value), str(refused.value)
    assert events.seen == [] and not any((tmp_path / "runs").iterdir())


def test_a_plan_the_preflight_refuses_does_not_start(tmp_path: Path) -> None:
    rig = one_sensor_twin(tmp_path)
    three_axes = QUICK.read_text().replace("model: sr207,", "model: sr207-aamu,").replace(
        "[sync, reference, scale_factor]", "[sync]")
    controller, events = _controller(tmp_path, rig, three_axes)
    _refused(controller, events, tmp_path, "sensor.model: sensor 'sr207-aamu' has the channels "
             "v_sz, v_sy, v_sx, but daq plugin 'sim' records v_sz, sync_pulse, trigger, "
             "temperature_c: v_sy, v_sx would not be recorded")


def _add(url: str, identifier: str, due_in_days: int) -> None:
    result = CliRunner().invoke(app, [
        "references", "add", identifier, "--kind", "encoder", "--certificate", f"C-{identifier}",
        "--issuing-lab", "National Lab", "--calibrated", str(TODAY - timedelta(days=400)),
        "--due", str(TODAY + timedelta(days=due_in_days)), "--accuracy", "±1 arcsec",
        "--records", url])
    assert result.exit_code == 0, result.output


def test_references_are_checked_and_named_on_the_certificate(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'records.sqlite'}"
    _add(url, "ENC-1", 30)
    _add(url, "ENC-0", -1)  # overdue since yesterday
    rig = tmp_path / "rig.yaml"
    rig.write_text("turntable: {plugin: sim}\ndaq: {plugin: sim}\nreferences: [ENC-1, ENC-0]\n")
    controller, events = _controller(tmp_path, rig, QUICK.read_text())
    _refused(controller, events, tmp_path, "reference 'ENC-0' (encoder, certificate C-ENC-0) "
             "was due on")
    rig.write_text("turntable: {plugin: sim}\ndaq: {plugin: sim}\nreferences: [ENC-1]\n")
    name = controller.start("lab/p.yaml", "Ada Operator", UnitName("SN-1"))
    assert events.ended.wait(120), [e["type"] for e in events.seen]
    assert events.seen[-1]["type"] == "finished", events.seen[-1]
    metadata = json.loads((tmp_path / "runs" / name / "results.json").read_text())["metadata"]
    assert [r["identifier"] for r in metadata["reference_standards"]] == ["ENC-1"]
    assert 'id="reference-standards"' in (tmp_path / "runs" / name / "report.html").read_text()
