"""What the ASCII-over-TCP chamber drivers (``espec``, ``simserv``) share: the link, the
soak/stability wait and the safe state.

The stabilisation criterion is the ``sim`` chamber's (docs/method.md §4.2): the soak time has
elapsed since the set point was commanded *and* the process value is within ``stable_band_c`` of
the set point. On a real chamber the driver measures time on the wall clock and sleeps
``poll_interval_s`` between reads; against an aatest simulator (its identification says
``SIMULATOR``) it reads the simulator's clock and asks it to advance instead of sleeping, so a
simulated soak runs in the twin's lab time. Every socket error, timeout or error reply becomes
a one-line :class:`~aatest.engine.errors.RigFault` naming the chamber; :meth:`LineChamber.off`
puts the chamber in standby (over a new connection when the link was reset) and never raises.
"""

from __future__ import annotations

import logging
import socket
import time

from pydantic import BaseModel, ConfigDict, Field

from aatest.engine.errors import EnvelopeRefused, RigFault, rig_boundary

log = logging.getLogger("aatest.chamber")


class LineChamberConfig(BaseModel):
    """Connection and stabilisation settings common to the ASCII chamber drivers."""

    model_config = ConfigDict(extra="forbid")
    host: str = "127.0.0.1"
    port: int = Field(10001, ge=1, le=65535)
    timeout_s: float = Field(2.0, gt=0, description="per-request answer timeout")
    stable_band_c: float = Field(0.2, gt=0, description="in band: |PV − SP| ≤ this")
    poll_interval_s: float = Field(5.0, gt=0, description="time between reads while soaking")
    max_wait_s: float = Field(4 * 3600.0, gt=0, description="longest stabilisation allowed")


class LineChamber:
    """Base of a chamber driver speaking one request/one reply lines over TCP."""

    #: the protocol's name in messages
    kind = "chamber"
    #: request terminator
    terminator = b"\r\n"

    def __init__(self, config: LineChamberConfig) -> None:
        self.config = config
        self.simulated = False
        self._sock: socket.socket | None = None
        self._buffer = b""
        self._setpoint_time_s = 0.0
        self._where = f"{self.kind} chamber {config.host}:{config.port}"

    # --- link ------------------------------------------------------------------------------
    def _connect(self) -> None:
        self._disconnect()
        try:
            self._sock = socket.create_connection((self.config.host, self.config.port),
                                                  timeout=self.config.timeout_s)
        except OSError as exc:
            raise RigFault(f"{self._where}: cannot connect ({exc})") from exc
        self._buffer = b""

    def _disconnect(self) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def _exchange(self, request: str) -> str:
        """Send one request, return its reply line (without terminator)."""
        if self._sock is None:
            raise RigFault(f"{self._where}: not connected ({request!r})")
        try:
            self._sock.sendall(request.encode("latin-1") + self.terminator)
            while b"\n" not in self._buffer:
                chunk = self._sock.recv(4096)
                if not chunk:
                    raise ConnectionResetError("connection closed by the chamber")
                self._buffer += chunk
        except TimeoutError as exc:
            self._disconnect()  # a late answer must not be taken for the next request's
            raise RigFault(f"{self._where}: no answer to {request!r} within "
                           f"{self.config.timeout_s:g} s") from exc
        except OSError as exc:
            self._disconnect()
            raise RigFault(f"{self._where}: connection lost during {request!r} "
                           f"({exc.__class__.__name__}: {exc})") from exc
        line, _, self._buffer = self._buffer.partition(b"\n")
        return line.rstrip(b"\r").decode("latin-1")

    # --- what each protocol supplies --------------------------------------------------------
    def _identify(self) -> str:
        raise NotImplementedError

    def _read_pv_sp(self) -> tuple[float, float]:
        raise NotImplementedError

    def _limits(self) -> tuple[float, float]:
        raise NotImplementedError

    def _command_setpoint(self, setpoint_c: float) -> None:
        raise NotImplementedError

    def _standby(self) -> None:
        raise NotImplementedError

    def _sim_clock_s(self) -> float:
        raise NotImplementedError

    def _sim_wait(self, seconds: float) -> None:
        raise NotImplementedError

    # --- Chamber protocol ------------------------------------------------------------------
    @rig_boundary
    def start(self) -> None:
        """Connect, identify (``simulated`` when the chamber says SIMULATOR), read PV."""
        self._connect()
        ident = self._identify()
        self.simulated = "SIMULATOR" in ident.upper()
        self._read_pv_sp()
        log.info("%s: %s%s", self._where, ident, " (simulated)" if self.simulated else "")

    def _clock_s(self) -> float:
        return self._sim_clock_s() if self.simulated else time.monotonic()

    def _sleep(self, seconds: float) -> None:
        if self.simulated:
            self._sim_wait(seconds)
        else:
            time.sleep(seconds)

    @rig_boundary
    def set_temperature(self, setpoint_c: float) -> None:
        """Refuse a set point outside the chamber's limits; else command it and run."""
        if self._sock is None:
            self._connect()
        low, high = self._limits()
        if not low <= setpoint_c <= high:
            raise EnvelopeRefused(f"{self._where}: set point {setpoint_c:g} °C outside the "
                                  f"chamber's limits [{low:g}, {high:g}] °C")
        self._command_setpoint(setpoint_c)
        self._setpoint_time_s = self._clock_s()

    @rig_boundary
    def wait_stable(self, soak_s: float) -> float:
        """Poll until ``soak_s`` has elapsed since the set point and PV is in band."""
        cfg = self.config
        while True:
            pv, sp = self._read_pv_sp()
            elapsed = self._clock_s() - self._setpoint_time_s
            if elapsed >= soak_s and abs(pv - sp) <= cfg.stable_band_c * (1 + 1e-9):
                return pv
            if elapsed > max(cfg.max_wait_s, soak_s):
                raise RigFault(f"{self._where}: not stable within {cfg.max_wait_s:g} s "
                               f"(PV {pv:g} °C, SP {sp:g} °C, band ±{cfg.stable_band_c:g})")
            self._sleep(cfg.poll_interval_s)

    def off(self) -> None:
        """Standby (heating and cooling off); never raises, reconnects once if needed."""
        for reconnect in (self._sock is None, True):
            try:
                if reconnect:
                    self._connect()
                self._standby()
                return
            except Exception as exc:  # noqa: BLE001 - the safe state must not raise
                log.error("%s: standby not confirmed%s: %s", self._where,
                          " after reconnecting" if reconnect else "", exc)
            if reconnect:
                return

    def close(self) -> None:
        self._disconnect()
