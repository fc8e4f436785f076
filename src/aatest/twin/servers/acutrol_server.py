"""``aatest sim-server acutrol``: the simulated ACUTROL-class controller on a TCP port.

:class:`AcutrolProtocol` answers each received line (``\\n``-terminated, a trailing ``\\r``
ignored) from an :class:`~aatest.twin.servers.acutrol_controller.AcutrolController`: the
queries' answers joined by ``;``, or — when the line held no query — ``OK`` (the MIT-licensed
AcutronicRobotics/acutrol driver expects ``OK`` after each command on TCP), or
``ERR <code>,"<text>"`` for the first command that failed (the rest of that line is not
carried out; the error also goes to the queue read by ``:SYSTEM:ERROR?``). Every reply is
preceded by an 8-byte header (that driver skips 8 bytes of every reply; what a real controller
puts there is not public, the simulator sends ``#`` and the payload length in 7 digits) and
ends with ``\\r\\n``. ``*IDN?`` contains ``SIMULATOR``.

:func:`serve_forever` serves the controller with the simulated CAN logger (the sensors of the
sensor model it is told, one channel each: :func:`sensor_rig_model`) and,
if asked, a simulated ESPEC or SIMSERV chamber on the *same* twin, so one process is a whole
simulated rig whose chamber heats the sensor that the table turns.
"""

from __future__ import annotations

import os
import threading

import aatest
from aatest.twin.model import RigModel
from aatest.twin.servers.acutrol_controller import MODE_LETTERS, AcutrolController
from aatest.twin.servers.acutrol_parse import Command, CommandError, axis_of, numbers, parse_line
from aatest.twin.servers.background import serve_until_interrupted
from aatest.twin.servers.line_server import LineServer
from aatest.twin.servers.sensor_models import sensor_rig_model
from aatest.twin.world import World

ACUTROL_PORT = 9888  # the MIT driver's default
HEADER_BYTES = 8


class AcutrolProtocol:
    """Line handling of the simulated controller."""

    terminator = b"\n"
    name = "ACUTROL controller"

    def __init__(self, controller: AcutrolController, header_bytes: int = HEADER_BYTES) -> None:
        self.controller = controller
        self.header_bytes = header_bytes

    def frame(self, reply: str) -> bytes:
        payload = reply.encode("latin-1")
        header = b""
        if self.header_bytes:
            header = (b"#" + str(len(payload)).zfill(self.header_bytes - 1).encode()
                      )[-self.header_bytes:]
        return header + payload + b"\r\n"

    def answer(self, line: str) -> str | None:
        ctl = self.controller
        with ctl.lock:
            answers: list[str] = []
            try:
                for command in parse_line(line):
                    reply = self._execute(command)
                    if reply is not None:
                        answers.append(reply)
                ctl.commit()
            except CommandError as exc:
                ctl.discard()
                ctl.errors.append(exc)
                return f"ERR {exc.code},\"{exc.text}\""
        return ";".join(answers) if answers else "OK"

    def _execute(self, command: Command) -> str | None:
        root = command.path[0]
        handler = {"*IDN": self._common, "*STB": self._common, "*OPC": self._common,
                   "*RST": self._common, "*CLS": self._common, "MODE": self._mode,
                   "DEMAND": self._demand, "LIMIT": self._limit, "INTERLOCK": self._interlock,
                   "READ": self._read, "UTILITY": lambda c: None, "SYSTEM": self._system,
                   "XLOG": self._xlog}.get(root)
        if handler is None or (len(command.path) == 1 and root not in ("MODE", "UTILITY")
                               and not root.startswith("*")):
            raise CommandError(-113, f"Undefined header {command.name}")
        return handler(command)

    def _common(self, command: Command) -> str | None:
        ctl, name = self.controller, command.path[0]
        if name == "*IDN":
            return f"ACUTRONIC,ACUTROL SIMULATOR,SIM-0001,aatest {aatest.__version__}"
        if name == "*STB":
            closed = all(a.interlock_closed for a in ctl.axes.values())
            return str((4 if ctl.errors else 0) | (1 if closed else 0))
        if name == "*OPC":
            return "1"
        if name == "*CLS":
            ctl.errors.clear()
            return None
        if name == "*RST":  # motion stopped, interlocks open, errors cleared
            for axis in ctl.axes:
                ctl.interlock(axis, False)
            ctl.errors.clear()
            return None
        raise CommandError(-113, f"Undefined header {name}")

    def _mode(self, command: Command) -> str | None:
        axis = axis_of(command)
        if command.query and len(command.path) == 1:
            return self.controller.axes[axis].mode
        if len(command.path) == 1:
            raise CommandError(-113, "Incomplete header :MODE")
        self.controller.set_mode(axis, MODE_LETTERS[command.path[1]])
        return None

    def _demand(self, command: Command) -> str | None:
        ctl, axis, leaf = self.controller, axis_of(command), command.path[1]
        if leaf == "POSITION":
            ctl.demand_position(axis, numbers(command, 1)[0])
        elif leaf == "RATE":
            ctl.demand_rate(axis, numbers(command, 1)[0])
        elif leaf == "OSCILLATION":
            amplitude, frequency = numbers(command, 2)
            ctl.demand_oscillation(axis, amplitude, frequency)
        else:
            raise CommandError(-221, f"Settings conflict; {command.name} needs a profile mode")
        return None

    def _limit(self, command: Command) -> str | None:
        kind = {"RATE": "rate", "ACCELERATION": "accel", "LOW": "low", "HIGH": "high",
                "VTRIP": "vtrip"}[command.path[1]]
        if command.query:
            if kind not in ("rate", "accel"):
                raise CommandError(-113, f"Undefined header {command.name}")
            args = tuple(a.upper() if a.isalpha() else a for a in command.args)
            mode = args[0] if args and args[0] in ("P", "R", "S", "A") else "P"
            rest = args[1:] if args and args[0] in ("P", "R", "S", "A") else args
            rate, accel = self.controller.limit(axis_of(Command(command.path, True, rest)), mode)
            return f"{rate if kind == 'rate' else accel:.6g}"
        self.controller.set_limit(command, kind)
        return None

    def _interlock(self, command: Command) -> str | None:
        leaf = command.path[1]
        axes = [axis_of(command)] if command.args else [1, 2]
        for axis in axes:
            if leaf == "RESET":
                self.controller.errors.clear()
            else:
                self.controller.interlock(axis, leaf == "CLOSE")
        return None

    def _read(self, command: Command) -> str:
        ctl, axis = self.controller, axis_of(command)
        table = ctl.world.table_state()  # the twin's motion at the controller's lab time
        leaf = command.path[1]
        if leaf == "POSITION":
            value = table.inner_deg if axis == 1 else table.outer_deg
        elif leaf == "RATE":
            value = table.inner_dps if axis == 1 else table.outer_dps
        else:
            value = 0.0
        return f"{value:.6f}"

    def _system(self, command: Command) -> str:
        errors = self.controller.errors
        if not errors:
            return '0,"No error"'
        error = errors.pop(0)
        return f"{error.code},\"{error.text}\""

    def _xlog(self, command: Command) -> str | None:
        ctl, leaf = self.controller, command.path[1]
        if leaf == "CONFIG":
            ctl.configure_log(command)
        elif leaf == "ARM":
            ctl.arm()
        elif leaf == "MOUNTING":
            ctl.set_mounting(command)
        elif leaf == "STATE":
            return ctl.log.state
        elif leaf == "HEADER":
            return ctl.header()
        else:
            return ctl.data(command)
        return None


def acutrol_server(host: str = "127.0.0.1", port: int = 0, seed: int = 0,
                   model: RigModel | None = None, world: World | None = None,
                   lock: threading.RLock | None = None,
                   lifetime_s: float | None = None) -> LineServer:
    """A :class:`LineServer` with a fresh controller (its own twin unless ``world`` given)."""
    if world is None:
        if model is None:
            from aatest.twin.defaults import realistic_rig_model

            model = realistic_rig_model()
        world = World(model, seed)
    controller = AcutrolController(world, lock)
    return LineServer(AcutrolProtocol(controller), host, port, lifetime_s)


def serve_forever(host: str, port: int, seed: int, *, chamber: str = "none",
                  chamber_port: int = 0, can_interface: str | None = None,
                  can_channel: str | None = None, sensor: str | None = None) -> None:
    """Serve the table, the simulated CAN logger and optionally a chamber until Ctrl-C; the
    twin carries the sensors of the sensor plugin ``sensor`` (:func:`sensor_rig_model`)."""
    from aatest.twin.servers.chamber_sim import SimChamberCore
    from aatest.twin.servers.modbus_server import (
        CAN_CHANNEL_ENV,
        CAN_INTERFACE_ENV,
        DEFAULT_CAN_CHANNEL,
        DEFAULT_CAN_INTERFACE,
    )

    interface = can_interface or os.environ.get(CAN_INTERFACE_ENV, DEFAULT_CAN_INTERFACE)
    channel = can_channel or os.environ.get(CAN_CHANNEL_ENV, DEFAULT_CAN_CHANNEL)
    table = acutrol_server(host, port, seed, model=sensor_rig_model(sensor))
    controller = table.protocol.controller  # type: ignore[attr-defined]
    servers, extras = [table], []
    channels = ",".join(s.channel for s in controller.world.model.sensors)
    banner = "aatest simulated ACUTROL controller: TCP {0}".replace("{0}", f"{host}:{{0}}")
    if chamber != "none":
        core = SimChamberCore(controller.world, controller.lock,
                              setpoint_c=controller.world.model.chamber.ambient_c)
        servers.append(chamber_server(chamber, core, host, chamber_port))
        banner += f", {chamber} chamber {host}:{{1}}"
    if interface != "none":
        from aatest.twin.servers.can_sim import SimCanLogger

        extras.append(SimCanLogger(controller, interface, channel).start())
        banner += f", CAN {interface} {channel} (sensors {channels})"
    serve_until_interrupted(servers, banner + " (Ctrl-C stops)", extras)


def chamber_server(kind: str, core: object, host: str = "127.0.0.1", port: int = 0,
                   lifetime_s: float | None = None) -> LineServer:
    """A simulated ``espec`` or ``simserv`` chamber on ``core``."""
    from aatest.twin.servers.chamber_sim import EspecProtocol, SimChamberCore, SimservProtocol

    assert isinstance(core, SimChamberCore)
    protocol = EspecProtocol(core) if kind == "espec" else SimservProtocol(core)
    return LineServer(protocol, host, port, lifetime_s)


def serve_chamber_forever(kind: str, host: str, port: int, seed: int) -> None:
    """``aatest sim-server espec|simserv``: a chamber with its own twin until Ctrl-C."""
    from aatest.twin.servers.chamber_sim import SimChamberCore

    server = chamber_server(kind, SimChamberCore.standalone(seed), host, port)
    serve_until_interrupted([server], f"aatest simulated {kind} chamber: TCP {host}:{{0}} "
                                      "(Ctrl-C stops)")
