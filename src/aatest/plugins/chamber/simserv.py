"""Weiss/Vötsch chamber over SIMSERV (ASCII over TCP, port 2049).

A request is the command number, the chamber index (always 1) and the arguments separated by
``¶`` (byte 0xB6), ended by ``\\r``; the reply's first field is 1 on success, negative on an
error, then the values (as in the public drivers, e.g. SengerM/VotschTechnik-climate-chamber-
Python). Used here: 11001 write set point, 11002 read set point, 11004 read temperature,
11007/11009 input limits, 14001 manual mode on (1)/off (0), 99997 identification.
Verified against aatest's simulator only (docs/driver-simserv.md).
"""

from __future__ import annotations

from pydantic import Field

from aatest.engine.errors import RigFault
from aatest.engine.interfaces import RigContext
from aatest.plugins.chamber._line import LineChamber, LineChamberConfig

SEP = "\u00b6"


class SimservChamber(LineChamber):
    """Weiss/Vötsch temperature chamber (SIMSERV)."""

    kind = "SIMSERV"
    terminator = b"\r"

    class Config(LineChamberConfig):
        """Connection (SIMSERV's fixed port 2049) and stabilisation settings."""

        port: int = Field(2049, ge=1, le=65535)

    def __init__(self, config: Config | None = None, context: RigContext | None = None) -> None:
        super().__init__(config if config is not None else self.Config())
        self.context = context

    def _query(self, number: int, *args: object) -> list[str]:
        request = SEP.join([str(number), "1", *(str(a) for a in args)])
        fields = self._exchange(request).strip().split(SEP)
        try:
            status = int(fields[0])
        except ValueError as exc:
            raise RigFault(f"{self._where}: malformed reply to {number}: {fields!r}") from exc
        if status != 1:
            raise RigFault(f"{self._where}: command {number} failed with code {status}")
        return fields[1:]

    def _float(self, number: int, *args: object) -> float:
        values = self._query(number, *args)
        try:
            return float(values[0])
        except (IndexError, ValueError) as exc:
            raise RigFault(f"{self._where}: malformed reply to {number}: {values!r}") from exc

    def _identify(self) -> str:
        return " ".join(self._query(99997, 1))

    def _read_pv_sp(self) -> tuple[float, float]:
        return self._float(11004, 1), self._float(11002, 1)

    def _limits(self) -> tuple[float, float]:
        return self._float(11007, 1), self._float(11009, 1)

    def _command_setpoint(self, setpoint_c: float) -> None:
        self._query(11001, 1, f"{setpoint_c:.2f}")
        self._query(14001, 1, 1)

    def _standby(self) -> None:
        self._query(14001, 1, 0)

    def _sim_clock_s(self) -> float:
        return self._float(99990)

    def _sim_wait(self, seconds: float) -> None:
        self._query(99991, f"{seconds:.3f}")
