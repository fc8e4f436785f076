"""``aatest sim-server modbus --sensor MODEL``: the simulator's twin carries the named unit's
sensors and its CAN logger serves their channels, as ``sim-server acutrol --sensor`` does."""

from __future__ import annotations

from typing import Any

import pytest
from typer.testing import CliRunner

from aatest.cli import app
from aatest.plugins.sensors.sr207 import SR207Unit
from aatest.twin.defaults import realistic_rig_model
from aatest.twin.servers import modbus_server


def _served(monkeypatch: pytest.MonkeyPatch, *options: str) -> tuple[Any, str]:
    """Run ``aatest sim-server modbus OPTIONS`` until it would serve; return its Modbus
    server (stopped) and its banner."""
    seen: dict[str, Any] = {}

    def capture(servers: list[Any], banner: str, extras: list[Any]) -> None:
        seen["server"], seen["banner"] = servers[0], banner
        for part in extras:
            part.stop()

    monkeypatch.setattr(modbus_server, "serve_until_interrupted", capture)
    result = CliRunner().invoke(app, ["sim-server", "modbus", "--port", "0", *options])
    assert result.exit_code == 0, result.output
    return seen["server"], seen["banner"]


def test_modbus_simulator_serves_the_sensors_of_the_named_model(
        monkeypatch: pytest.MonkeyPatch) -> None:
    server, banner = _served(monkeypatch, "--sensor", "sr207-aamu", "--can-interface",
                             "virtual", "--can-channel", "sensor-model-test")
    model = server.controller.world.model
    assert [(s.channel, s.axis) for s in model.sensors] == [("v_sz", "I"), ("v_sy", "O"),
                                                            ("v_sx", "P")]
    assert model == realistic_rig_model(SR207Unit().datasheet())
    assert "CAN virtual sensor-model-test (sensors v_sz,v_sy,v_sx)" in banner


def test_modbus_simulator_without_a_sensor_serves_the_reference_sensor(
        monkeypatch: pytest.MonkeyPatch) -> None:
    server, banner = _served(monkeypatch, "--can-interface", "virtual", "--can-channel",
                             "sensor-model-test")
    assert [s.channel for s in server.controller.world.model.sensors] == ["v_sz"]
    assert "(sensors v_sz)" in banner


def test_modbus_simulator_refuses_an_unknown_sensor_model() -> None:
    result = CliRunner().invoke(app, ["sim-server", "modbus", "--port", "0", "--sensor",
                                      "sr999", "--can-interface", "none"])
    assert result.exit_code == 2
    assert "no sensor plugin named 'sr999' (installed: " in result.output
