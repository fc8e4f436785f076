"""The unit named at the station reaches the run as ``run --serial`` does; a real rig refuses
an unnamed unit before it moves.

The rig is the twin behind its Modbus and CAN simulator servers posing as hardware (the
drivers then take the real-rig path); the station's run controller is driven directly, as the
page's Start does, and its published events are collected.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from run_events import Events
from served_rig import served_rig

from aatest.engine.run.session import UnitName
from aatest.protocols.modbus_map import Command
from aatest.station.catalogue import Procedures, RunsDirHistory
from aatest.station.control import RunController

SEED = 5
PROCEDURE = """\
procedure: served
description: One coherent 1 Hz sine through the served rig.
sensor: {model: sr207}
sampling: {rate_hz: 2000, samples: 8000, settle_s: 1}
steps:
  - sine: {axis: inner, frequency_hz: 1.0, accel_dps2: 400, snap: coherent}
analysis: [sync, reference, scale_factor]
report: {template: calibration-certificate, sign: false}
"""
#: commands that move the table or record
MOTION = {Command.START_MOTION, Command.ARM_LOG}


@dataclass
class Hardware:
    rig: Path
    lab: Path
    commands: list[Command]


@pytest.fixture
def hardware(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Hardware]:
    """The served twin posing as an ACME controller and a real CAN logger."""
    monkeypatch.setenv("AATEST_RECORDS", f"sqlite:///{tmp_path / 'records.sqlite'}")
    with served_rig(tmp_path, monkeypatch, SEED, f"station-{tmp_path.name}",
                    hardware_name="ACME TC-2 controller") as served:
        lab = tmp_path / "lab"
        lab.mkdir()
        (lab / "served.yaml").write_text(PROCEDURE)
        yield Hardware(served.rig, lab, served.commands)


def _start(hardware: Hardware, tmp_path: Path, unit: UnitName) -> tuple[Events, Path]:
    events = Events()
    runs = tmp_path / "runs"
    runs.mkdir(exist_ok=True)
    controller = RunController(Procedures(hardware.lab), RunsDirHistory(runs), hardware.rig,
                               events)
    name = controller.start("lab/served.yaml", "Ada Operator", unit)
    assert events.ended.wait(120), [e["type"] for e in events.seen]
    return events, runs / name


def test_an_unnamed_unit_is_refused_on_a_real_rig_before_motion(
    hardware: Hardware, tmp_path: Path
) -> None:
    events, _run_dir = _start(hardware, tmp_path, UnitName())
    final = events.seen[-1]
    assert final["type"] == "stopped" and final["exit_code"] == 2
    assert "no unit serial" in final["reason"]
    assert not MOTION & set(hardware.commands), hardware.commands  # the table never moved


def test_the_serial_named_at_the_station_is_the_unit_calibrated(
    hardware: Hardware, tmp_path: Path
) -> None:
    events, run_dir = _start(hardware, tmp_path, UnitName("SN-STATION-7"))
    final = events.seen[-1]
    assert final["type"] == "finished", final
    assert next(e for e in events.seen if e["type"] == "run_dir")["serial"] == "SN-STATION-7"
    results = json.loads((run_dir / "results.json").read_text())
    assert results["metadata"]["sensor"]["serial"] == "SN-STATION-7"
    assert results["metadata"]["kind"] == "calibration"  # hardware, named: a calibration
    assert final["files"] == ["report.html", "results.json"]  # no PDF asked: none linked
