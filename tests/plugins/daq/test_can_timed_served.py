"""A long static step on the served rig in one process (the modbus table over TCP, the CAN logger
on the virtual bus, unpaced): the table's head log is armed before the logger's timed record
starts, and the step records and analyses through both real drivers."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from served_rig import served_rig
from typer.testing import CliRunner

from aatest.cli import app
from aatest.protocols.modbus_map import Command
from aatest.twin.defaults import realistic_rig_model

#: 12 s static steps at 2 kHz against a declared table log of 4 000 samples (2 s): streamed
PROCEDURE = """\
procedure: served-long
sensor: {model: sr207, serial: "S-1"}
sampling: {rate_hz: 2000, settle_s: 1}
steps:
  - static: {label: up, inner_deg: 0, outer_deg: 0, duration_s: 12, motor_on: false}
  - static: {label: down, inner_deg: 0, outer_deg: 180, duration_s: 12, motor_on: false}
analysis: [sync, bias, noise, drift]
report: {template: calibration-certificate, sign: false}
"""
HEAD_SAMPLES = 4000

pytestmark = pytest.mark.slow  # ≈ 20 s on a loaded 2-core machine


def test_head_is_armed_before_the_timed_record(tmp_path: Path,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    with served_rig(tmp_path, monkeypatch, 3, f"timed-{tmp_path.name}") as served:
        served.rig.write_text(served.rig.read_text().replace(
            "retries: 0}", f"retries: 0, envelope: {{log_capacity_samples: {HEAD_SAMPLES}}}}}"))
        events: list[Any] = served.commands  # the table's commands, and the logger's records
        stream = served.server.controller.daq_stream

        def noted(samples: int) -> Any:
            events.append(("timed record", samples))
            return stream(samples)

        monkeypatch.setattr(served.server.controller, "daq_stream", noted)
        procedure = tmp_path / "p.yaml"
        procedure.write_text(PROCEDURE)
        result = CliRunner().invoke(app, ["run", str(procedure), "--rig", str(served.rig),
                                          "--out", str(tmp_path / "run"), "--no-progress"])
    assert result.exit_code == 0, result.output
    timed = [i for i, e in enumerate(events) if isinstance(e, tuple)]
    assert [events[i] for i in timed] == [("timed record", 24_000)] * 2
    for i in timed:  # the head was armed after the step's motion started, before the record
        before = events[:i]
        assert before[-1] == Command.ARM_LOG and before[-2] == Command.START_MOTION
    analysis = json.loads((tmp_path / "run" / "results.json").read_text())["analysis"]
    daq = realistic_rig_model().daq  # the record: the logger's lead, 12 s and its stop lag
    record_s = daq.start_lead_s + 12.0 + daq.stop_lag_s
    for sync in analysis["sync"]["steps"]:  # fitted on the 2 s head; the edges nearest its
        # ends fall a pulse period (10 ms) inside it: 2 % slack
        assert sync["fit_coverage"] == pytest.approx(HEAD_SAMPLES / 2000 / record_s, rel=0.02)
    assert analysis["noise"]["v_sz"]["record_s"] == pytest.approx(12.0, rel=1e-3)
