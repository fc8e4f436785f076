"""ESPEC chamber (P300-class controller) over its ASCII TCP interface (port 10001).

Commands as used by the MIT-licensed EspecNorthAmerica/ChamberConnectLibrary (``p300.py``,
``especinteract.py``): ``<command>\\r\\n`` out, one ``<reply>\\r\\n`` back, ``NA:<reason>`` for an
error. ``TEMP?`` answers ``PV,SP,HIGH,LOW``; ``TEMP, S25.0`` sets the set point;
``MODE,CONSTANT`` runs it, ``MODE,STANDBY`` stops heating and cooling; ``ROM?`` identifies.
Verified against aatest's simulator only (docs/driver-espec.md).
"""

from __future__ import annotations

from pydantic import Field

from aatest.engine.errors import RigFault
from aatest.engine.interfaces import RigContext
from aatest.plugins.chamber._line import LineChamber, LineChamberConfig

#: ``TEMP?`` answers process value, set point, high and low limit
TEMP_FIELDS = 4


class EspecChamber(LineChamber):
    """ESPEC temperature chamber."""

    kind = "ESPEC"
    terminator = b"\r\n"

    class Config(LineChamberConfig):
        """Connection (ESPEC's default port 10001) and stabilisation settings."""

        port: int = Field(10001, ge=1, le=65535)

    def __init__(self, config: Config | None = None, context: RigContext | None = None) -> None:
        super().__init__(config if config is not None else self.Config())
        self.context = context

    def _query(self, command: str) -> str:
        reply = self._exchange(command)
        if reply.startswith("NA:"):
            raise RigFault(f"{self._where}: {command!r} refused: {reply[3:].strip()}")
        return reply

    def _temp(self) -> list[float]:
        reply = self._query("TEMP?")
        try:
            values = [float(v) for v in reply.split(",")[:4]]
        except ValueError as exc:
            raise RigFault(f"{self._where}: malformed TEMP? reply {reply!r}") from exc
        if len(values) != TEMP_FIELDS:
            raise RigFault(f"{self._where}: malformed TEMP? reply {reply!r}")
        return values

    def _identify(self) -> str:
        return self._query("ROM?")

    def _read_pv_sp(self) -> tuple[float, float]:
        pv, sp, _high, _low = self._temp()
        return pv, sp

    def _limits(self) -> tuple[float, float]:
        _pv, _sp, high, low = self._temp()
        return low, high

    def _command_setpoint(self, setpoint_c: float) -> None:
        self._query(f"TEMP, S{setpoint_c:.1f}")
        self._query("MODE,CONSTANT")

    def _standby(self) -> None:
        self._query("MODE,STANDBY")

    def _sim_clock_s(self) -> float:
        return float(self._query("SIM CLOCK?"))

    def _sim_wait(self, seconds: float) -> None:
        self._query(f"SIM WAIT, {seconds:.3f}")
