"""The simulated DAQ records the twin's sensors: beside a table that does not move the twin it
is refused at ``validate`` (exit 2, naming both plugins) instead of failing the first step."""

from __future__ import annotations

from pathlib import Path

from typer.testing import CliRunner

from aatest.cli import app
from aatest.engine.interfaces import RigContext, SensorDatasheet, daq_refusal
from aatest.engine.steps import SensorRef
from aatest.plugins.daq.sim import SimDaq
from aatest.plugins.turntable.modbus import ModbusTurntable
from aatest.plugins.turntable.sim import SimTurntable

PROCEDURE = """\
procedure: follows
sensor: {model: sr207, serial: "F1"}
sampling: {rate_hz: 2000, samples: 4096, settle_s: 0.5}
steps:
  - sine: {axis: inner, frequency_hz: 2.0, accel_dps2: 100, snap: coherent}
analysis: [sync, frf]
report: {template: frequency-response, sign: false}
"""


def _context() -> RigContext:
    return RigContext(sensor=SensorRef(model="sr207"), datasheet=SensorDatasheet(model="sr207"))


def test_follows_the_simulated_table_in_either_construction_order() -> None:
    ctx = _context()
    daq = SimDaq(SimDaq.Config(), ctx)  # built before the table: asked only once both exist
    table = SimTurntable(SimTurntable.Config(), ctx)
    assert daq_refusal(daq, table) is None


def test_refuses_a_table_that_does_not_move_the_twin() -> None:
    ctx = _context()
    table = ModbusTurntable(ModbusTurntable.Config(port=9), ctx)
    reason = daq_refusal(SimDaq(SimDaq.Config(), ctx), table)
    assert reason is not None and "ModbusTurntable does not" in reason


def test_validate_refuses_the_sim_daq_beside_a_real_table(tmp_path: Path) -> None:
    (tmp_path / "p.yaml").write_text(PROCEDURE)
    rig = tmp_path / "rig.yaml"
    rig.write_text("turntable: {plugin: modbus, port: 9}\ndaq: {plugin: sim}\n")
    for extra in (["validate"], ["run", "--out", str(tmp_path / "run")]):
        result = CliRunner().invoke(app, [*extra, str(tmp_path / "p.yaml"), "--rig", str(rig)])
        assert result.exit_code == 2, result.output
        assert ("error: daq plugin 'sim' cannot record beside turntable plugin 'modbus': the "
                "simulated DAQ records the digital twin's sensors") in result.output
    assert not (tmp_path / "run").exists()  # refused before a run directory was made
