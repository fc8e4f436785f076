"""Fault matrix of the ``acutrol`` table and the ``espec``/``simserv`` chambers (issue 25): a
link reset, a black hole, a stalled request or the simulator dying (its server closed at that
request, what ``kill -9`` does to its sockets) at any instant of a run ends in exit 3 with one
reason line, the table stopped (motor off, interlocks open) and the chamber in standby where
they can still be reached, the steps already recorded kept, and ``run --resume`` completes.

The faults come from :class:`line_proxy.LineFaultProxy` between each driver and its simulator
(same machinery as the Modbus matrix, :mod:`tcp_proxy`). A few instants run in the fast suite;
the rest, and ``kill -9`` of a real ``aatest sim-server acutrol`` process, under ``-m slow``.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from line_proxy import LineFaultProxy
from tcp_proxy import Action, Trigger
from test_acutrol_procedure import RigProcess, multicast_group
from typer.testing import CliRunner

from aatest.cli import app
from aatest.engine.errors import EXIT_RIG_FAULT
from aatest.twin.servers.acutrol_server import acutrol_server, chamber_server
from aatest.twin.servers.can_sim import SimCanLogger
from aatest.twin.servers.chamber_sim import SimChamberCore
from aatest.twin.servers.line_server import LineServer

SEED = 13
TIMEOUT_S = 1.0  # the drivers' reply timeout (a loaded 2-core machine answers a first
#: request in up to ~0.5 s); a stall lasts 3× as long
PROCEDURE = """\
procedure: line-fault-matrix
sensor: {model: sr207, serial: "A1234"}
rig: {turntable: sim, daq: sim, chamber: sim}
sampling: {rate_hz: 2000, samples: 2000, settle_s: 0.5}
steps:
  - temperature_steps:
      setpoints_c: [22, 30]
      soak_s: 60
      off_wait_s: 10
      static: true
      dynamic: {axis: inner, frequency_hz: 1.0, accel_dps2: 400}
analysis: [sync, scale_factor]  # bias needs a ±1 g pair; the matrix needs any analysis
report: {template: calibration-certificate, sign: false}
"""
STEPS = 4  # two set points × (static, sine)


def line(text: str) -> Callable[[str], bool]:
    return lambda request: text in request


#: (which link, request text, occurrence, action): ≥ 10 instants per driver
TABLE_INSTANTS: dict[str, tuple[str, int, Action]] = {
    "connect-idn-reset": ("*IDN?", 1, "reset"),
    "connect-limits-blackhole": (":LIMIT:RATE S,2", 1, "blackhole"),
    "connect-interlock-stall": (":INTERLOCK:RESET", 1, "stall"),
    "move-demand-kill": (":DEMAND:POSITION", 1, "kill"),
    "move-read-reset": (":READ:POSITION?", 2, "reset"),
    "settle-config-blackhole": (":XLOG:CONFIG", 1, "blackhole"),
    "settle-oscillation-reset": (":DEMAND:OSCILLATION", 1, "reset"),
    "settle-arm-stall": (":XLOG:ARM", 2, "stall"),
    "record-state-kill": (":XLOG:STATE?", 4, "kill"),
    "record-header-reset": (":XLOG:HEADER?", 1, "reset"),
    "download-data-blackhole": (":XLOG:DATA?", 5, "blackhole"),
    "download-data-kill": (":XLOG:DATA?", 14, "kill"),
    "download-step3-stall": (":XLOG:DATA?", 25, "stall"),
    "stop-mode-reset": (":MODE:POSITION 1;:MODE:POSITION 2", 4, "reset"),
}
ESPEC_INSTANTS: dict[str, tuple[str, int, Action]] = {
    "connect-rom-reset": ("ROM?", 1, "reset"),
    "connect-temp-blackhole": ("TEMP?", 1, "blackhole"),
    "setpoint-limits-stall": ("TEMP?", 2, "stall"),
    "setpoint-kill": ("TEMP, S", 1, "kill"),
    "run-reset": ("MODE,CONSTANT", 1, "reset"),
    "soak-poll-blackhole": ("TEMP?", 6, "blackhole"),
    "soak-wait-stall": ("SIM WAIT", 3, "stall"),
    "soak-clock-kill": ("SIM CLOCK?", 4, "kill"),
    "second-setpoint-reset": ("TEMP, S", 2, "reset"),
    "second-soak-blackhole": ("SIM WAIT", 9, "blackhole"),
}
SIMSERV_INSTANTS: dict[str, tuple[str, int, Action]] = {
    "connect-info-reset": ("99997\xb6", 1, "reset"),
    "connect-pv-blackhole": ("11004\xb6", 1, "blackhole"),
    "setpoint-limits-stall": ("11007\xb6", 1, "stall"),
    "setpoint-kill": ("11001\xb6", 1, "kill"),
    "start-reset": ("14001\xb61\xb61\xb61", 1, "reset"),
    "soak-pv-blackhole": ("11004\xb6", 5, "blackhole"),
    "soak-wait-stall": ("99991\xb6", 3, "stall"),
    "soak-clock-kill": ("99990\xb6", 4, "kill"),
    "second-setpoint-reset": ("11001\xb6", 2, "reset"),
    "second-soak-blackhole": ("99991\xb6", 9, "blackhole"),
}
FAST = {("table", "settle-oscillation-reset"), ("table", "download-data-kill"),
        ("table", "connect-interlock-stall"), ("espec", "soak-poll-blackhole"),
        ("simserv", "setpoint-kill")}


@dataclass
class Bench:
    """The simulated rig (one twin: table, chamber, CAN logger) behind two fault proxies."""

    tmp_path: Path
    chamber: str
    table: LineServer | None = None
    room: LineServer | None = None
    logger: SimCanLogger | None = None
    proxies: dict[str, LineFaultProxy] = field(default_factory=dict)
    dead: list[LineServer] = field(default_factory=list)

    def power_on(self) -> None:
        """Start a (fresh) simulated rig; point the proxies at it."""
        self.table = acutrol_server(seed=SEED, lifetime_s=120.0)
        controller = self.table.protocol.controller  # type: ignore[attr-defined]
        core = SimChamberCore(controller.world, controller.lock,
                              setpoint_c=controller.world.model.chamber.ambient_c)
        self.room = chamber_server(self.chamber, core, lifetime_s=120.0)
        self.logger = SimCanLogger(controller, "virtual", f"lines-{self.tmp_path.name}").start()
        self.table.start()
        self.room.start()
        for name, server, term in (("table", self.table, b"\n"),
                                   ("chamber", self.room, self.terminator)):
            if name not in self.proxies:
                self.proxies[name] = LineFaultProxy(server.port, term)
            self.proxies[name].upstream_port = server.port

    @property
    def terminator(self) -> bytes:
        return b"\r" if self.chamber == "simserv" else b"\n"

    def kill(self) -> None:
        """The whole simulated rig dies (one process): every socket closes, state is lost."""
        for part in (self.table, self.room):
            if part is not None:
                part.stop(timeout_s=2.0)
                self.dead.append(part)
        if self.logger is not None:
            self.logger.stop()

    def rig_file(self) -> Path:
        rig = self.tmp_path / "rig.yaml"
        rig.write_text(
            f"turntable: {{plugin: acutrol, port: {self.proxies['table'].port}, "
            f"timeout_s: {TIMEOUT_S}, poll_interval_s: 0.01}}\n"
            f"daq: {{plugin: can, interface: virtual, channel: lines-{self.tmp_path.name}, "
            "response_timeout_s: 1.0, frame_timeout_s: 1.0}\n"
            f"chamber: {{plugin: {self.chamber}, port: {self.proxies['chamber'].port}, "
            f"timeout_s: {TIMEOUT_S}, poll_interval_s: 10}}\n")
        return rig

    def close(self) -> None:
        for proxy in self.proxies.values():
            proxy.close()
        self.kill()


def _run(procedure: Path, rig: Path, out: Path, *extra: str) -> tuple[int, str]:
    result = CliRunner().invoke(app, ["run", str(procedure), "--rig", str(rig), "--out",
                                      str(out), "--seed", str(SEED), "--no-progress",
                                      "--confirm-prompts", "auto", *extra])
    return result.exit_code, result.output


def fault_then_resume(bench: Bench, link: str, text: str, occurrence: int,
                      action: Action) -> str:
    """Arm the fault, run to exit 3, check the safe state, heal, resume to the end."""
    proxy = bench.proxies[link]
    proxy.trigger = Trigger(line(text), occurrence, action, stall_s=3 * TIMEOUT_S,  # type: ignore[arg-type]
                            on_fire=bench.kill if action == "kill" else None)
    procedure = bench.tmp_path / "procedure.yaml"
    procedure.write_text(PROCEDURE)
    rig, out = bench.rig_file(), bench.tmp_path / "run"
    code, output = _run(procedure, rig, out)
    assert proxy.fired is not None, f"the fault never fired: {output}"
    assert code == EXIT_RIG_FAULT, output
    errors = [row for row in output.splitlines() if row.startswith("error:")]
    assert len(errors) == 1 and "Traceback" not in output, output
    if action != "kill":
        _assert_safe_state(bench, link, action)
    proxy.heal()
    if action == "kill":
        bench.power_on()  # the operator restarts the simulated rig
    code, output = _run(procedure, rig, out, "--resume")
    assert code == 0, output
    steps = json.loads((out / "results.json").read_text())["steps"]
    assert len(steps) == STEPS
    return errors[0]


def _assert_safe_state(bench: Bench, link: str, action: Action) -> None:
    """Where the safe stop could reach them: motor off, interlocks open; chamber standby."""
    assert bench.table is not None and bench.room is not None
    controller = bench.table.protocol.controller  # type: ignore[attr-defined]
    core = bench.room.protocol.core  # type: ignore[attr-defined]
    if not (link == "table" and action == "blackhole"):
        assert not controller.world.motor_on
        assert not any(a.interlock_closed for a in controller.axes.values())
    if not (link == "chamber" and action == "blackhole") and core.mode != "STANDBY":
        # a chamber never started (fault before its set point) was never switched on
        assert core.mode == "STANDBY"


CASES = [("table", name, *spec) for name, spec in TABLE_INSTANTS.items()] + [
    (kind, name, *spec) for kind, instants in (("espec", ESPEC_INSTANTS),
                                               ("simserv", SIMSERV_INSTANTS))
    for name, spec in instants.items()]


def _params(fast: bool) -> list:
    return [pytest.param(*case, id=f"{case[0]}-{case[1]}") for case in CASES
            if ((case[0], case[1]) in FAST) == fast]


@pytest.fixture
def bench_for(tmp_path: Path) -> Iterator[Callable[[str], Bench]]:
    benches: list[Bench] = []

    def make(chamber: str) -> Bench:
        bench = Bench(tmp_path, chamber)
        bench.power_on()
        benches.append(bench)
        return bench

    yield make
    for bench in benches:
        bench.close()


def _case(bench_for: Callable[[str], Bench], driver: str, text: str, occurrence: int,
          action: Action) -> None:
    bench = bench_for("espec" if driver == "table" else driver)
    reason = fault_then_resume(bench, "table" if driver == "table" else "chamber", text,
                               occurrence, action)
    where = "ACUTROL controller" if driver == "table" else f"{driver.upper()} chamber"
    assert where in reason, reason


@pytest.mark.parametrize(("driver", "name", "text", "occurrence", "action"), _params(True))
def test_fault_at_an_instant_exits_3_safe_and_resumable(
        bench_for: Callable[[str], Bench], driver: str, name: str, text: str,
        occurrence: int, action: Action) -> None:
    _case(bench_for, driver, text, occurrence, action)


@pytest.mark.slow
@pytest.mark.parametrize(("driver", "name", "text", "occurrence", "action"), _params(False))
def test_fault_matrix_long(bench_for: Callable[[str], Bench], driver: str, name: str,
                          text: str, occurrence: int, action: Action) -> None:
    _case(bench_for, driver, text, occurrence, action)


@pytest.mark.slow
@pytest.mark.parametrize(("text", "occurrence"), [(":XLOG:ARM", 1), (":XLOG:DATA?", 10),
                                                  ("SIM WAIT", 4)])
def test_kill_9_of_the_simulator_process_exits_3_and_resumes(
        tmp_path: Path, text: str, occurrence: int) -> None:
    """``kill -9`` of ``aatest sim-server acutrol --chamber espec`` at that request."""
    group = multicast_group()
    processes = [RigProcess("espec", group).start()]
    table, room = LineFaultProxy(processes[0].table_port), LineFaultProxy(processes[0].chamber_port)
    proxy = room if text.startswith("SIM") else table
    proxy.trigger = Trigger(line(text), occurrence, "kill",  # type: ignore[arg-type]
                            on_fire=processes[0].kill)
    procedure = tmp_path / "procedure.yaml"
    procedure.write_text(PROCEDURE)
    rig = processes[0].rig_file(tmp_path / "rig.yaml", table.port, room.port, TIMEOUT_S)
    out = tmp_path / "run"
    try:
        code, output = _run(procedure, rig, out)
        assert code == EXIT_RIG_FAULT and proxy.fired is not None, output
        proxy.heal()
        processes.append(RigProcess("espec", group).start())  # the operator restarts it
        table.upstream_port, room.upstream_port = (processes[-1].table_port,
                                                   processes[-1].chamber_port)
        code, output = _run(procedure, rig, out, "--resume")
        assert code == 0, output
    finally:
        table.close()
        room.close()
        for process in processes:
            process.stop()
