"""The twin served behind the Modbus table and the CAN logger on loopback, counting commands.

One set-up for the tests that drive the served rig through the real drivers (simulation
marking, the station's unit checks): the servers, a rig file naming them, and the list of
every command the table executed (a refusal "before motion" is checked on it).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import pytest

from aatest.protocols.modbus_map import Command
from aatest.twin.servers.can_sim import SimCanLogger
from aatest.twin.servers.modbus_server import SimModbusServer


@dataclass
class ServedRig:
    server: SimModbusServer
    logger: SimCanLogger
    rig: Path
    commands: list[Command]


@contextmanager
def served_rig(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, seed: int, channel: str,
               hardware_name: str | None = None) -> Iterator[ServedRig]:
    """The served rig, its rig file in ``tmp_path``; ``hardware_name``: the controller and the
    logger pose as real hardware (``simulated`` false) under that identification."""
    server = SimModbusServer(seed=seed, lifetime_s=120.0)
    logger = SimCanLogger(server.controller, "virtual", channel).start()
    server.attach(logger)
    server.start()
    if hardware_name is not None:
        server.controller.pose_as_hardware(hardware_name)
        logger.simulated = False
    commands: list[Command] = []
    execute = server.controller._execute

    def counted(command: Command | None) -> None:
        if command is not None:
            commands.append(command)
        execute(command)

    monkeypatch.setattr(server.controller, "_execute", counted)
    rig = tmp_path / "rig.yaml"
    rig.write_text(
        f"turntable: {{plugin: modbus, host: 127.0.0.1, port: {server.port}, timeout_s: 2.0, "
        f"retries: 0}}\ndaq: {{plugin: can, interface: virtual, channel: {channel}}}\n"
        "chamber: {plugin: none}\n")
    try:
        yield ServedRig(server, logger, rig, commands)
    finally:
        server.stop()
        logger.stop()
