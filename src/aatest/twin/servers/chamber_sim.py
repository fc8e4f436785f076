"""Simulated temperature chambers behind their real ASCII protocols: ESPEC (P300-class) and
Weiss/Vötsch SIMSERV, both on top of the twin's chamber (first-order sensor thermal lag).

:class:`SimChamberCore` holds the chamber state (mode, set point, limits) and drives a
:class:`~aatest.twin.world.World`: a set point in force while the chamber runs steps the
World's thermal model, exactly as the in-process ``sim`` chamber does. Its clock is the
World's lab time, advanced only by events (never by the wall clock), like the simulated
Modbus controller's: a 15 min soak does not take 15 min. The driver waits through a
simulator-only *wait* command (``SIM WAIT, <s>`` on ESPEC, ``99991`` on SIMSERV) and reads the
clock with ``SIM CLOCK?`` / ``99990``; neither exists on a real chamber, whose driver sleeps on
the wall clock instead. In standby the simulated sensor keeps following the last set point's
lag, as the twin's chamber does after ``off`` (the short record after switching off).

Wire formats (public sources, see docs/driver-espec.md and docs/driver-simserv.md):

- ESPEC: ``<command>\\r\\n`` → ``<reply>\\r\\n``; ``TEMP?`` → ``PV,SP,HIGH,LOW``;
  ``TEMP, S25.0`` → ``OK: TEMP, S25.0``; ``MODE,CONSTANT|STANDBY|OFF``; ``MODE?``; ``MON?`` →
  ``PV,,MODE,ALARMS``; errors ``NA:CMD ERR``, ``NA:PARA ERR``, ``NA:DATA OUT OF RANGE``
  (EspecNorthAmerica/ChamberConnectLibrary, MIT). ``ROM?`` names the simulator.
- SIMSERV: ``<number>¶<chamber>¶<args…>\\r`` (¶ = 0xB6) → ``1¶<values…>\\r\\n``; a negative
  first field is an error. 11001 set point, 11002 read set point, 11004 read temperature,
  11007/11009 input limits, 14001 manual mode on/off, 10012 status, 99997 info
  (SengerM/VotschTechnik-climate-chamber-Python, after the public SIMSERV descriptions).
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from dataclasses import dataclass, field

from aatest.twin.model import RigModel
from aatest.twin.world import World

ESPEC_PORT = 10001
SIMSERV_PORT = 2049
SIMSERV_SEP = "\u00b6"  # ¶, byte 0xB6 in latin-1
SIMULATOR_ID = "AATEST SIMULATOR"
#: the longest single simulator wait (a day; a driver polls far more often)
MAX_WAIT_S = 86_400.0


@dataclass
class SimChamberCore:
    """Mode, set point and limits of a chamber, driving a World's thermal model."""

    world: World
    lock: threading.RLock = field(default_factory=threading.RLock)
    high_limit_c: float = 100.0
    low_limit_c: float = -40.0
    setpoint_c: float = 22.0
    mode: str = "STANDBY"
    alarms: int = 0

    @classmethod
    def standalone(cls, seed: int = 0, model: RigModel | None = None) -> SimChamberCore:
        """A chamber with its own twin (``aatest sim-server espec|simserv`` alone)."""
        if model is None:
            from aatest.twin.defaults import realistic_rig_model

            model = realistic_rig_model()
        return cls(World(model, seed), setpoint_c=model.chamber.ambient_c)

    def temperature_c(self) -> float:
        with self.lock:
            return self.world.sensor_temperature_c()

    def set_setpoint(self, value_c: float) -> bool:
        """Store a set point (stepped into the twin while running); False beyond the limits."""
        if not (math.isfinite(value_c) and self.low_limit_c <= value_c <= self.high_limit_c):
            return False
        with self.lock:
            self.setpoint_c = float(value_c)
            if self.mode == "CONSTANT":
                self.world.set_temperature(self.setpoint_c)
        return True

    def set_mode(self, mode: str) -> None:
        with self.lock:
            if mode == "CONSTANT" and self.mode != "CONSTANT":
                self.world.set_temperature(self.setpoint_c)
            self.mode = mode

    def clock_s(self) -> float:
        with self.lock:
            return float(self.world.lab_time_s)

    def wait(self, seconds: float) -> bool:
        """Advance lab time (the simulator-only stand-in for the driver's sleep)."""
        if not (math.isfinite(seconds) and 0 <= seconds <= MAX_WAIT_S):
            return False
        with self.lock:
            self.world.lab_time_s += float(seconds)
        return True


def _number(text: str) -> float | None:
    try:
        value = float(text)
    except ValueError:
        return None
    return value if math.isfinite(value) else None


class EspecProtocol:
    """The ESPEC P300-class command subset, answering from a :class:`SimChamberCore`."""

    terminator = b"\r\n"
    name = "ESPEC chamber"

    def __init__(self, core: SimChamberCore) -> None:
        self.core = core

    def frame(self, reply: str) -> bytes:
        return reply.encode("latin-1") + b"\r\n"

    def answer(self, line: str) -> str | None:
        command = line.strip().upper()
        head, _, args = command.partition(",")
        head, args = head.strip(), args.strip()
        handler = self._handlers().get(head)
        if handler is None:
            return "NA:CMD ERR"
        reply = handler(args)
        return reply if reply.startswith("NA:") or head.endswith("?") else f"OK: {line.strip()}"

    def _handlers(self) -> dict[str, Callable[[str], str]]:
        return {"TEMP?": self._temp_query, "TEMP": self._temp_set, "MODE?": self._mode_query,
                "MODE": self._mode_set, "MON?": self._mon, "ROM?": self._rom,
                "TYPE?": self._type, "SIM CLOCK?": self._clock, "SIM WAIT": self._wait}

    def _temp_query(self, _args: str) -> str:
        core = self.core
        return (f"{core.temperature_c():.2f},{core.setpoint_c:.1f},"
                f"{core.high_limit_c:.1f},{core.low_limit_c:.1f}")

    def _temp_set(self, args: str) -> str:
        """``TEMP, S<sp> H<high> L<low>`` (any subset, space separated)."""
        fields = args.split()
        if not fields:
            return "NA:PARA ERR"
        parsed = [(f[:1], _number(f[1:])) for f in fields]
        if any(key not in "SHL" or value is None for key, value in parsed):
            return "NA:PARA ERR"
        values = {key: float(value) for key, value in parsed if value is not None}
        high = values.get("H", self.core.high_limit_c)
        low = values.get("L", self.core.low_limit_c)
        if low >= high:
            return "NA:DATA OUT OF RANGE"
        self.core.high_limit_c, self.core.low_limit_c = high, low
        if "S" in values and not self.core.set_setpoint(values["S"]):
            return "NA:DATA OUT OF RANGE"
        return "OK"

    def _mode_query(self, _args: str) -> str:
        return self.core.mode

    def _mode_set(self, args: str) -> str:
        if args not in ("CONSTANT", "STANDBY", "OFF"):
            return "NA:PARA ERR"
        self.core.set_mode(args)
        return "OK"

    def _mon(self, _args: str) -> str:
        core = self.core
        return f"{core.temperature_c():.2f},,{core.mode},{core.alarms}"

    def _rom(self, _args: str) -> str:
        return f"P300 {SIMULATOR_ID} 1.0"

    def _type(self, _args: str) -> str:
        return f"T,P300,{self.core.high_limit_c:.1f}"

    def _clock(self, _args: str) -> str:
        return f"{self.core.clock_s():.3f}"

    def _wait(self, args: str) -> str:
        value = _number(args)
        return "OK" if value is not None and self.core.wait(value) else "NA:PARA ERR"


class SimservProtocol:
    """The SIMSERV command subset, answering from a :class:`SimChamberCore`.

    Error codes (first reply field): -5 unknown command, -6 wrong arguments, -8 value outside
    the input limits (the simulator's choice; only "negative = error" is public).
    """

    terminator = b"\r"
    name = "SIMSERV chamber"

    def __init__(self, core: SimChamberCore) -> None:
        self.core = core
        self.running = False

    def frame(self, reply: str) -> bytes:
        return reply.encode("latin-1") + b"\r\n"

    def answer(self, line: str) -> str | None:
        fields = line.strip().split(SIMSERV_SEP)
        if not fields[0].isdigit() or fields[1:2] != ["1"]:
            return "-5"
        command, args = int(fields[0]), fields[2:]
        handler = self._handlers().get(command)
        if handler is None:
            return "-5"
        values = handler(args)
        if isinstance(values, int):
            return str(values)
        return SIMSERV_SEP.join(["1", *values])

    def _handlers(self) -> dict[int, Callable[[list[str]], list[str] | int]]:
        return {11001: self._set_setpoint, 11002: self._read_setpoint, 11004: self._read_pv,
                11007: self._low, 11009: self._high, 14001: self._manual, 10012: self._status,
                99997: self._info, 99990: self._clock, 99991: self._wait}

    @staticmethod
    def _variable(args: list[str], extra: int = 0) -> bool:
        """Control variable 1 (temperature) and ``extra`` more arguments."""
        return len(args) == 1 + extra and args[0] == "1"

    def _set_setpoint(self, args: list[str]) -> list[str] | int:
        value = _number(args[1]) if self._variable(args, 1) else None
        if value is None:
            return -6
        return [] if self.core.set_setpoint(value) else -8

    def _read_setpoint(self, args: list[str]) -> list[str] | int:
        return [f"{self.core.setpoint_c:.2f}"] if self._variable(args) else -6

    def _read_pv(self, args: list[str]) -> list[str] | int:
        return [f"{self.core.temperature_c():.2f}"] if self._variable(args) else -6

    def _low(self, args: list[str]) -> list[str] | int:
        return [f"{self.core.low_limit_c:.2f}"] if self._variable(args) else -6

    def _high(self, args: list[str]) -> list[str] | int:
        return [f"{self.core.high_limit_c:.2f}"] if self._variable(args) else -6

    def _manual(self, args: list[str]) -> list[str] | int:
        if not self._variable(args, 1) or args[1] not in ("0", "1"):
            return -6
        self.running = args[1] == "1"
        self.core.set_mode("CONSTANT" if self.running else "STANDBY")
        return []

    def _status(self, args: list[str]) -> list[str] | int:
        return ["1" if self.core.mode == "CONSTANT" else "0"] if not args else -6

    def _info(self, args: list[str]) -> list[str] | int:
        info = {"1": f"VT {SIMULATOR_ID}", "2": "26", "3": "SIM-0001"}
        return [info[args[0]]] if len(args) == 1 and args[0] in info else -6

    def _clock(self, args: list[str]) -> list[str] | int:
        return [f"{self.core.clock_s():.3f}"] if not args else -6

    def _wait(self, args: list[str]) -> list[str] | int:
        value = _number(args[0]) if len(args) == 1 else None
        return [] if value is not None and self.core.wait(value) else -6
