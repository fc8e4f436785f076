"""Conformance rigs of aatest's own drivers (entry-point group ``aatest.conformance``): each
starts the driver's simulator on a loopback port and declares the faults it can produce."""

from __future__ import annotations

import itertools
from collections.abc import Callable
from typing import Any

from aatest.testing.conformance import ConformanceRig, build, short_step
from aatest.twin.model import RigModel
from aatest.twin.servers.line_server import LineServer

FAULT_TIMEOUT_S = 1.0  # the drivers' reply timeout in these rigs


class _Restartable:
    """A simulator server that can die (sockets close) and be restarted on the same port."""

    def __init__(self, server: LineServer) -> None:
        self.server = server

    def dies(self) -> None:
        self.server.stop(timeout_s=2.0)

    def hang(self) -> None:
        self.server.faults.hanging = True

    def recover(self) -> None:
        """Remove injected faults; a dead server is started again (same instrument state)."""
        self.server.recover()
        if not self.server.running:
            fresh = LineServer(self.server.protocol, self.server.host, self.server.port)
            self.server = fresh.start()

    def close(self) -> None:
        self.server.stop()


def acutrol() -> ConformanceRig:
    """The ACUTROL simulator; the test calls ``daq_start`` where the CAN logger would."""
    from aatest.twin.servers.acutrol_server import acutrol_server

    server = acutrol_server(model=RigModel()).start()
    controller = server.protocol.controller  # type: ignore[attr-defined]
    served = _Restartable(server)

    def trips() -> None:  # the interlock opens by itself (an operator opened the door)
        with controller.lock:
            controller.interlock(1, False)

    def is_safe() -> bool:
        return not controller.world.motor_on and not any(
            axis.interlock_closed for axis in controller.axes.values())

    return ConformanceRig(
        options={"port": server.port, "timeout_s": FAULT_TIMEOUT_S, "poll_interval_s": 0.01,
                 "log_margin_s": 5.0, "move_timeout_s": 5.0},
        faults={"stops-answering": served.hang, "dies": served.dies, "interlock-trips": trips},
        recover=served.recover, is_safe=is_safe, close=served.close,
        trigger=controller.daq_start, fault_timeout_s=8 * FAULT_TIMEOUT_S)


def _chamber(kind: str) -> ConformanceRig:
    from aatest.twin.servers.acutrol_server import chamber_server
    from aatest.twin.servers.chamber_sim import SimChamberCore

    core = SimChamberCore.standalone(model=RigModel())
    server = chamber_server(kind, core).start()
    served = _Restartable(server)
    return ConformanceRig(
        options={"port": server.port, "timeout_s": FAULT_TIMEOUT_S, "poll_interval_s": 5.0},
        faults={"stops-answering": served.hang, "dies": served.dies},
        recover=served.recover, is_safe=lambda: core.mode in ("STANDBY", "OFF"),
        close=served.close,
        fault_timeout_s=4 * FAULT_TIMEOUT_S)


def espec() -> ConformanceRig:
    """The ESPEC simulator with its own twin."""
    return _chamber("espec")


def simserv() -> ConformanceRig:
    """The SIMSERV simulator with its own twin."""
    return _chamber("simserv")



class _ModbusProcess:
    """``aatest sim-server modbus`` in its own process: the Modbus table and, on a
    udp_multicast group of its own, the CAN logger fed by the same twin."""

    _seeds = itertools.count(1)

    def __init__(self) -> None:
        from aatest.testing.sim_process import SimServerProcess, multicast_group

        seed = next(self._seeds)
        self.group = multicast_group(seed)
        self.server = SimServerProcess("modbus", args=(
            "--seed", str(seed), "--can-interface", "udp_multicast",
            "--can-channel", self.group)).start()
        self.trigger_daq: Any = None

    def table_options(self) -> dict[str, Any]:
        return {"host": "127.0.0.1", "port": self.server.port, "timeout_s": FAULT_TIMEOUT_S,
                "retries": 0, "log_margin_s": 10.0, "move_timeout_s": 10.0}

    def daq_options(self) -> dict[str, Any]:
        return {"interface": "udp_multicast", "channel": self.group, "channels": ["v_sz"],
                "response_timeout_s": FAULT_TIMEOUT_S, "frame_timeout_s": FAULT_TIMEOUT_S}

    def table(self) -> Any:
        return build("turntable", "modbus", ConformanceRig(
            options=self.table_options(), faults={}, recover=self.recover,
            is_safe=self.is_safe, close=self.close))

    def trigger(self) -> None:
        """The CAN logger starts logging: its trigger line starts the table log."""
        if self.trigger_daq is None:
            self.trigger_daq = build("daq", "can", ConformanceRig(
                options=self.daq_options(), faults={}, recover=self.recover,
                is_safe=self.is_safe, close=self.close))
            self.trigger_daq.start()
        self.trigger_daq.start_logging(short_step())

    def is_safe(self) -> bool:
        """Motion stopped and motor off, read from the controller's status word."""
        from pymodbus.client import ModbusTcpClient

        from aatest.protocols.modbus_map import Reg, Status

        client = ModbusTcpClient("127.0.0.1", port=self.server.port, timeout=2.0, retries=1)
        try:
            client.connect()
            status = Status(client.read_holding_registers(int(Reg.STATUS), count=1).registers[0])
        finally:
            client.close()
        return Status.MOTOR_ON not in status and Status.MOVING not in status

    def recover(self) -> None:
        self.server.restart()

    def close(self) -> None:
        if self.trigger_daq is not None:
            self.trigger_daq.close()
        self.server.stop()

    def rig(self, options: dict[str, Any], partner: Callable[[], Any] | None = None,
            bad_options: tuple[dict[str, Any], ...] = ()) -> ConformanceRig:
        # SIGSTOP: the controller stops answering; SIGKILL: kill -9 of the sim-server
        return ConformanceRig(
            options=options, faults={"stops-answering": self.server.freeze,
                                     "dies": self.server.kill},
            recover=self.recover, is_safe=self.is_safe, close=self.close,
            trigger=self.trigger, partner=partner, bad_options=bad_options,
            fault_timeout_s=8 * FAULT_TIMEOUT_S)


def modbus() -> ConformanceRig:
    """The Modbus table against ``aatest sim-server modbus`` in a separate process; the CAN
    logger of that process raises the trigger."""
    served = _ModbusProcess()
    return served.rig(served.table_options(), bad_options=({"port": 0}, {"timeout_s": -1.0}))


def can() -> ConformanceRig:
    """The CAN logger against ``aatest sim-server modbus`` in a separate process (udp_multicast),
    recording beside the Modbus table of the same process."""
    served = _ModbusProcess()
    return served.rig(served.daq_options(), partner=served.table,
                      bad_options=({"sample_rate_hz": 0.0}, {"on_frame_loss": "ignore"},
                                   {"node_id": 16}))
