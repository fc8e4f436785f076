"""Fault-injection matrix (issue 14): a link or controller failure at any instant of a run —
connect, move, settle, record, log download, stop — ends in exit 3 with one reason line, keeps
the steps already recorded, and ``run --resume`` then completes the run.

Faults come from a loopback proxy between the Modbus driver and the simulated controller
(:mod:`tcp_proxy`: reset, black-hole, stall at the n-th matching request), from stopping the
controller's server at a chosen request (what the OS does to its sockets on ``kill -9``), and
from bursts of lost CAN frames. Slow (``-m slow``): a 96-case long matrix, and ``kill -9`` of a
real ``aatest sim-server modbus`` process (CAN on udp_multicast) that is then restarted.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from tcp_proxy import Action, FaultProxy, Request, Trigger
from typer.testing import CliRunner

from aatest.cli import app
from aatest.engine.errors import EXIT_RIG_FAULT
from aatest.protocols.modbus_map import Command, Reg
from aatest.testing.sim_process import SimServerProcess
from aatest.twin.servers.can_sim import CanFaultInjection, SimCanLogger
from aatest.twin.servers.modbus_server import SimModbusServer

SEED = 11
# the driver's per-request timeout; a stall lasts 3× as long. 1 s, not 0.5 s: on a loaded
# 2-core machine (load average 17, measured) the first request of a connection took > 0.5 s,
# so the run failed before the armed instant and the case reported the wrong fault
TIMEOUT_S = 1.0
PROCEDURE = """\
procedure: fault-matrix
sensor: {model: sr207, serial: "A1234"}
rig: {turntable: sim, daq: sim, chamber: none}
sampling: {rate_hz: 2000, samples: 2000, settle_s: 0.5}
steps:
  - multi_position: {positions: [[0, 0], [0, 180]], repetitions: 1, mountings: [original]}
analysis: [sync, bias]
report: {template: calibration-certificate, sign: false}
"""
STEP_FILES = ["001-s001-static-i0-o0-original-r1.mcap", "002-s002-static-i0-o180-original-r1.mcap"]


def any_request(_request: Request) -> bool:
    return True


def command(which: Command) -> Callable[[Request], bool]:
    return lambda r: r.address == Reg.COMMAND and r.values[:1] == (int(which),)


def reads(reg: Reg) -> Callable[[Request], bool]:
    return lambda r: r.function == 3 and r.address == reg


def writes(reg: Reg) -> Callable[[Request], bool]:
    return lambda r: r.function in (16, 23) and r.address == reg


#: (phase, request matcher, occurrence): where the fault hits; each is tried with one action
INSTANTS: dict[str, tuple[Callable[[Request], bool], int, Action]] = {
    "connect-first-request-reset": (any_request, 1, "reset"),
    "connect-limits-blackhole": (any_request, 4, "blackhole"),
    "connect-user-limits-stall": (any_request, 8, "stall"),
    "connect-clear-faults-reset": (command(Command.CLEAR_FAULTS), 1, "reset"),
    "connect-motor-on-kill": (command(Command.MOTOR_ON), 1, "kill"),
    "move-demand-reset": (writes(Reg.MODE), 1, "reset"),
    "move-start-blackhole": (command(Command.START_MOTION), 1, "blackhole"),
    "move-poll-stall": (reads(Reg.STATUS), 3, "stall"),
    "move-step2-kill": (command(Command.START_MOTION), 3, "kill"),
    "move-step2-reset": (command(Command.START_MOTION), 3, "reset"),
    "settle-label-reset": (writes(Reg.LOG_LABEL), 1, "reset"),
    "settle-start-stall": (command(Command.START_MOTION), 2, "stall"),
    "settle-step2-blackhole": (command(Command.START_MOTION), 4, "blackhole"),
    "settle-step2-label-kill": (writes(Reg.LOG_LABEL), 2, "kill"),
    "record-log-id-reset": (reads(Reg.LOG_ID), 1, "reset"),
    "record-arm-blackhole": (command(Command.ARM_LOG), 1, "blackhole"),
    "record-arm-kill": (command(Command.ARM_LOG), 1, "kill"),
    "record-step2-arm-stall": (command(Command.ARM_LOG), 2, "stall"),
    "record-step2-log-id-reset": (reads(Reg.LOG_ID), 3, "reset"),
    "download-first-window-reset": (writes(Reg.WINDOW_CHANNEL), 1, "reset"),
    "download-window-20-blackhole": (writes(Reg.WINDOW_CHANNEL), 20, "blackhole"),
    "download-window-60-stall": (writes(Reg.WINDOW_CHANNEL), 60, "stall"),
    "download-window-100-kill": (writes(Reg.WINDOW_CHANNEL), 100, "kill"),
    "download-step2-window-5-reset": (writes(Reg.WINDOW_CHANNEL), 5, "reset"),
    "stop-command-reset": (command(Command.STOP), 1, "reset"),
    "stop-command-blackhole": (command(Command.STOP), 1, "blackhole"),
    "stop-command-stall": (command(Command.STOP), 1, "stall"),
    "stop-step2-kill": (command(Command.STOP), 2, "kill"),
    "stop-step2-reset": (command(Command.STOP), 2, "reset"),
}
#: bursts of lost CAN sample frames (first frame, burst length) in the first record
CAN_BURSTS = {"can-burst-1": (10, 1), "can-burst-50": (500, 50), "can-burst-400": (1200, 400)}


@dataclass
class Lab:
    """A simulated controller + CAN logger behind a fault proxy, and a rig file for it."""

    tmp_path: Path
    proxy: FaultProxy | None = None
    servers: list[SimModbusServer] = field(default_factory=list)
    logger: SimCanLogger | None = None
    #: the rig file's daq line; default the in-process logger on a virtual bus
    daq: str | None = None

    @property
    def channel(self) -> str:
        return f"matrix-{self.tmp_path.name}"

    def power_on(self) -> SimModbusServer:
        """Start a (fresh) controller and logger; point the proxy at it."""
        server = SimModbusServer(seed=SEED, lifetime_s=60.0)
        self.logger = SimCanLogger(server.controller, "virtual", self.channel).start()
        server.attach(self.logger)
        server.start()
        self.servers.append(server)
        if self.proxy is None:
            self.proxy = FaultProxy(server.port)
        self.proxy.upstream_port = server.port
        return server

    def rig_file(self) -> Path:
        assert self.proxy is not None
        rig = self.tmp_path / "rig.yaml"
        rig.write_text(
            f"turntable: {{plugin: modbus, host: 127.0.0.1, port: {self.proxy.port}, "
            f"timeout_s: {TIMEOUT_S}, retries: 0, poll_interval_s: 0.01}}\n"
            f"daq: {self.daq or self._virtual_daq}\n"
            "chamber: {plugin: none}\n"
        )
        return rig

    @property
    def _virtual_daq(self) -> str:
        return (
            f"{{plugin: can, interface: virtual, channel: {self.channel}, "
            "response_timeout_s: 2.0, frame_timeout_s: 2.0}"
        )

    def close(self) -> None:
        if self.proxy is not None:
            self.proxy.close()
        for server in self.servers:
            server.stop()


@pytest.fixture
def lab(rig_entry_points: None, tmp_path: Path) -> Iterator[Lab]:
    bench = Lab(tmp_path)
    bench.power_on()
    yield bench
    bench.close()


def _run(procedure: Path, rig: Path, out: Path, *extra: str) -> tuple[int, str]:
    result = CliRunner().invoke(
        app,
        [
            "run",
            str(procedure),
            "--rig",
            str(rig),
            "--out",
            str(out),
            "--seed",
            str(SEED),
            "--no-progress",
            "--confirm-prompts",
            "auto",
            *extra,
        ],
    )
    return result.exit_code, result.output


def _fault_then_resume(lab: Lab, heal: Callable[[], None]) -> tuple[str, list[str]]:
    """Run until the armed fault; check exit 3 and one reason line; heal; resume to the end.

    Returns the reason line and the step files kept after the fault.
    """
    procedure = lab.tmp_path / "procedure.yaml"
    procedure.write_text(PROCEDURE)
    rig, out = lab.rig_file(), lab.tmp_path / "run"
    code, output = _run(procedure, rig, out)
    assert code == EXIT_RIG_FAULT, output
    errors = [line for line in output.splitlines() if line.startswith("error:")]
    assert len(errors) == 1, output
    assert "internal error" not in output and "Traceback" not in output, output
    kept = sorted(p.name for p in (out / "steps").glob("*.mcap"))
    assert set(kept) <= set(STEP_FILES)
    heal()
    code, output = _run(procedure, rig, out, "--resume")
    assert code == 0, output
    steps = json.loads((out / "results.json").read_text())["steps"]
    assert [s["id"] for s in steps] == [name[4:-5] for name in STEP_FILES]
    return errors[0], kept


@pytest.mark.parametrize("instant", list(INSTANTS), ids=list(INSTANTS))
def test_link_fault_at_any_instant_exits_3_and_resumes(lab: Lab, instant: str) -> None:
    _link_fault(lab, instant, *INSTANTS[instant])


def _link_fault(
    lab: Lab, instant: str, match: Callable[[Request], bool], occurrence: int, action: Action
) -> None:
    """Fire ``action`` at the ``occurrence``-th request matching ``match``; exit 3; resume."""
    proxy, server = lab.proxy, lab.servers[0]
    assert proxy is not None
    # "kill": the controller dies at that request; its sockets close and its state is lost
    on_fire = (lambda: server.stop(timeout_s=2.0)) if action == "kill" else None
    proxy.trigger = Trigger(match, occurrence, action, stall_s=3 * TIMEOUT_S, on_fire=on_fire)

    def heal() -> None:
        assert proxy.fired is not None, f"{instant}: the fault never fired"
        proxy.heal()
        if action == "kill":
            lab.power_on()  # the operator restarts the controller

    reason, _kept = _fault_then_resume(lab, heal)
    assert "Modbus controller 127.0.0.1" in reason, reason
    if action == "reset":  # the controller was reachable again: safe_stop switched it off
        assert not server.controller.world.motor_on, "safe state: motor off"


@pytest.mark.parametrize("burst", list(CAN_BURSTS), ids=list(CAN_BURSTS))
def test_can_frame_loss_burst_exits_3_and_resumes(lab: Lab, burst: str) -> None:
    first, length = CAN_BURSTS[burst]
    assert lab.logger is not None
    logger = lab.logger

    logger.faults = CanFaultInjection(
        drop_frames=frozenset(range(first, first + length)), record_number=1
    )

    def heal() -> None:
        logger.faults = CanFaultInjection()

    reason, kept = _fault_then_resume(lab, heal)
    assert f"lost {length} of" in reason and "CAN logger node 1" in reason, reason
    assert kept == []  # the first record is the damaged one: nothing of it is kept


#: the long matrix: every action at many more instants (window reads, status polls, requests).
#: Each instant must exist in every run: a clean run of PROCEDURE reads STATUS 9 or 10 times
#: (measured five times: one poll per wait, a second when a wait is not yet done — how often
#: depends on the machine's speed), so the status polls stop at the 7th; the 13th–29th, tried
#: before, never came on a quiet machine, where the run then rightly ended with exit 0.
LONG_INSTANTS = {
    f"{name}-{n}-{action}": (match, n, action)
    for name, match, counts in (
        ("request", any_request, range(1, 60, 7)),
        ("status-poll", reads(Reg.STATUS), range(1, 9, 2)),
        ("window", writes(Reg.WINDOW_CHANNEL), range(1, 400, 37)),
    )
    for n in counts
    for action in ("reset", "blackhole", "stall", "kill")
}


@pytest.mark.slow
@pytest.mark.parametrize("instant", list(LONG_INSTANTS), ids=list(LONG_INSTANTS))
def test_long_matrix_exits_3_and_resumes(lab: Lab, instant: str) -> None:
    _link_fault(lab, instant, *LONG_INSTANTS[instant])


#: kill -9 of a real ``aatest sim-server modbus`` process, at instants like the measured ones
#: (issue 14: 1.5, 2 and 2.5 s into a static multi-position run ended with exit 1 on main)
PROCESS_KILLS = {
    "settle": (command(Command.START_MOTION), 2),
    "record": (command(Command.ARM_LOG), 1),
    "download": (writes(Reg.WINDOW_CHANNEL), 30),
}


def server_process(group: str) -> SimServerProcess:
    """``aatest sim-server modbus`` in its own process, its CAN logger on udp_multicast."""
    env = {**os.environ, "AATEST_SIM_CAN_CHANNEL": group,
           "AATEST_SIM_CAN_INTERFACE": "udp_multicast"}
    server = SimServerProcess("modbus", args=("--seed", str(SEED)), env=env).start()
    assert f"127.0.0.1:{server.port}" in server.banner
    return server


@pytest.mark.slow
@pytest.mark.parametrize("instant", list(PROCESS_KILLS), ids=list(PROCESS_KILLS))
def test_kill_9_of_the_server_process_exits_3_and_resumes(
    rig_entry_points: None, tmp_path: Path, instant: str
) -> None:
    pytest.importorskip("msgpack", reason="python-can's udp_multicast needs msgpack")
    group = f"239.74.164.{10 + os.getpid() % 240}"
    servers = [server_process(group)]
    match, occurrence = PROCESS_KILLS[instant]
    proxy = FaultProxy(servers[0].port, Trigger(match, occurrence, "kill", on_fire=servers[0].kill))
    lab = Lab(
        tmp_path, proxy=proxy, daq=f"{{plugin: can, interface: udp_multicast, channel: '{group}'}}"
    )

    def heal() -> None:
        assert proxy.fired is not None
        proxy.heal()
        servers.append(server_process(group))  # the operator restarts the controller
        proxy.upstream_port = servers[-1].port

    try:
        reason, _kept = _fault_then_resume(lab, heal)
        assert "Modbus controller 127.0.0.1" in reason, reason
    finally:
        proxy.close()
        for server in servers:
            server.stop()
