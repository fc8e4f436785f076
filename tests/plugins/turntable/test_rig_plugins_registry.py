"""The modbus and can plugins pass the registry's validation, and a rig file naming them is
validated (options, envelope) without connecting to anything."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from aatest.cli import app
from aatest.engine import registry
from aatest.engine.errors import PluginError

PROCEDURE = """\
procedure: validate-only
sensor: {model: sr207, serial: "A1234"}
rig: {turntable: sim, daq: sim, chamber: none}
sampling: {rate_hz: 2000, samples: 4000, settle_s: 1}
steps:
  - sine: {axis: inner, frequency_hz: 1.0, accel_dps2: 150, snap: coherent}
analysis: [sync]
"""


@pytest.mark.usefixtures("rig_entry_points")
def test_plugins_validate_on_load() -> None:
    table = registry.load("turntable", "modbus")
    daq = registry.load("daq", "can")
    dist = table.distribution  # aatest itself once pyproject.toml declares the entry points
    assert dist in ("aatest", "aatest-rig-plugins") and daq.distribution == dist
    config = registry.configure(table, {"host": "10.0.0.7", "port": 502, "unit_id": 3})
    assert config.port == 502  # type: ignore[attr-defined]
    with pytest.raises(PluginError, match=rf"turntable plugin 'modbus' \({dist}\): "
                                          r"bad options: hots: Extra inputs are not permitted"):
        registry.configure(table, {"hots": "10.0.0.7"})
    with pytest.raises(PluginError, match="on_frame_loss"):
        registry.configure(daq, {"on_frame_loss": "ignore"})


@pytest.mark.usefixtures("rig_entry_points")
def test_validate_checks_the_declared_envelope_without_connecting(tmp_path: Path) -> None:
    (tmp_path / "p.yaml").write_text(PROCEDURE)
    rig = tmp_path / "rig.yaml"
    # nothing listens on port 9: validate must not connect; the declared envelope is narrow
    rig.write_text("turntable: {plugin: modbus, port: 9, envelope: {inner: {rate_dps: 1200, "
                   "accel_dps2: 100}}}\ndaq: {plugin: can, interface: virtual}\n")
    result = CliRunner().invoke(app, ["validate", str(tmp_path / "p.yaml"), "--rig", str(rig)])
    assert result.exit_code == 2 and "accel" in result.output, result.output
    rig.write_text("turntable: {plugin: modbus, port: 9}\ndaq: {plugin: can}\n")
    result = CliRunner().invoke(app, ["validate", str(tmp_path / "p.yaml"), "--rig", str(rig)])
    assert result.exit_code == 0, result.output
