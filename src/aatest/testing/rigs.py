"""Conformance rigs of aatest's own drivers (entry-point group ``aatest.conformance``): each
starts the driver's simulator on a loopback port and declares the faults it can produce."""

from __future__ import annotations

from aatest.testing.conformance import ConformanceRig
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

