"""A simulated Modbus controller (and CAN logger) per test, on OS-chosen loopback ports."""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterator
from importlib import metadata

import pytest

from aatest.plugins.daq.can import CanDaq
from aatest.plugins.turntable.modbus import ModbusTurntable
from aatest.twin.model import RigModel
from aatest.twin.servers.can_sim import CanFaultInjection, SimCanLogger
from aatest.twin.servers.modbus_controller import FaultInjection
from aatest.twin.servers.modbus_server import SimModbusServer

_channels = itertools.count()


class SimRig:
    """A served controller + CAN logger and the two real drivers pointed at them."""

    def __init__(self, faults: FaultInjection | None, can_faults: CanFaultInjection | None,
                 timeout_s: float) -> None:
        self.channel = f"aatest-test-{next(_channels)}"
        self.server = SimModbusServer(seed=3, model=RigModel(), faults=faults, lifetime_s=60.0)
        self.logger = SimCanLogger(self.server.controller, "virtual", self.channel,
                                   faults=can_faults).start()
        self.server.attach(self.logger)
        self.server.start()
        self.turntable = ModbusTurntable(ModbusTurntable.Config(
            port=self.server.port, timeout_s=timeout_s, retries=0, log_margin_s=10.0), None)
        self.daq = CanDaq(CanDaq.Config(channel=self.channel, response_timeout_s=1.0,
                                        frame_timeout_s=1.0), None)

    def close(self) -> None:
        self.turntable.safe_stop()
        self.turntable.close()
        self.daq.close()
        self.server.stop()


@pytest.fixture
def make_rig() -> Iterator[Callable[..., SimRig]]:
    rigs: list[SimRig] = []

    def factory(faults: FaultInjection | None = None, can_faults: CanFaultInjection | None = None,
                timeout_s: float = 1.0) -> SimRig:
        rig = SimRig(faults, can_faults, timeout_s)
        rigs.append(rig)
        return rig

    yield factory
    for rig in rigs:
        rig.close()


@pytest.fixture
def rig_entry_points(tmp_path_factory: pytest.TempPathFactory,
                     monkeypatch: pytest.MonkeyPatch) -> None:
    """Install the modbus/can entry points as a distribution on sys.path (until the project's
    own metadata declares them), so the registry discovers them the ordinary way."""
    declared = {ep.name for ep in metadata.entry_points(group="aatest.turntables")}
    if "modbus" in declared:
        return
    site = tmp_path_factory.mktemp("site")
    info = site / "aatest_rig_plugins-0.1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: aatest-rig-plugins\n"
                                   "Version: 0.1.0\n")
    (info / "entry_points.txt").write_text(
        "[aatest.turntables]\nmodbus = aatest.plugins.turntable.modbus:ModbusTurntable\n\n"
        "[aatest.daqs]\ncan = aatest.plugins.daq.can:CanDaq\n")
    monkeypatch.syspath_prepend(str(site))
