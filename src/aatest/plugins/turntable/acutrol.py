"""Turntable plugin for an ACUTROL-class two-axis controller (Acutronic), through PyVISA.

The command language is the public one (MIT-licensed AcutronicRobotics/acutrol driver,
williamsea/Acutrol; docs/driver-acutrol.md): colon-tree commands, the axis (1 = inner,
2 = outer) as first argument — ``:INTERLOCK:CLOSE 1``, ``:MODE:POSITION 1``,
``:DEMAND:POSITION 1,10.5``, ``:MODE:SYNTHESIS 1`` + ``:DEMAND:OSCILLATION 1,amp,freq,phase``,
``:MODE:RATE 1`` + ``:DEMAND:RATE 1,rate``, ``:LIMIT:RATE S,1,v``, ``:READ:POSITION? 1``,
``*IDN?``. Transport is a VISA session (``TCPIP::host::port::SOCKET`` with pyvisa-py, or
``GPIB0::1::INSTR`` with a vendor VISA); the TCP reply framing (an 8-byte header the MIT
driver skips, an ``OK`` after each command) is *not publicly verified* and therefore a
setting (:class:`AcutrolTurntable.Config`).

The reference log (2 kHz position/rate/acceleration and the freeze pulse) has no command in
the public set; the plugin reads it through the simulator-side ``:XLOG`` convention
(reference path ``controller-log``) and refuses to start on a controller that does not answer
it, naming the gap. On the simulator (``*IDN?`` names a SIMULATOR) a step's pivot or re-mount
is passed on with ``:XLOG:MOUNTING``, the operator's act the simulator carries out. Every VISA
error, timeout or ``ERR`` reply is a one-line
:class:`~aatest.engine.errors.RigFault`; :meth:`AcutrolTurntable.safe_stop` switches the modes
off and opens the interlocks (motion stopped, motor off), reconnecting once, and never raises.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from aatest.engine.errors import RigFault, rig_boundary
from aatest.engine.interfaces import RigContext, TableEnvelope, TableStatus
from aatest.engine.logs import TABLE, TABLE_CHANNELS, SampledLog
from aatest.engine.steps import PlannedStep

log = logging.getLogger("aatest.turntable.acutrol")
AXIS = {"inner": 1, "outer": 2}
#: ``:XLOG:DATA?`` channel numbers (0 = time, then the table log channels in order)
LOG_CHANNELS = ("time_s", *TABLE_CHANNELS)
#: *IDN? fields: maker, model, serial, firmware
IDN_SERIAL_FIELD = 2
#: a position reading this close to the demand is in position (the reads carry 6 decimals)
IN_POSITION_DEG = 1e-3
#: the live status query: both axes' position (°) and rate (°/s) in one line, one reply
STATUS_QUERY = ":READ:POSITION? 1;RATE? 1;POSITION? 2;RATE? 2"


class AcutrolTurntable:
    """A two-axis rate table on an ACUTROL-class controller."""

    class Config(BaseModel):
        """Where the controller is, how its replies are framed, timing and the envelope."""

        model_config = ConfigDict(extra="forbid")
        resource: str | None = Field(None, description="VISA resource; default "
                                     "TCPIP::<host>::<port>::SOCKET")
        host: str = "127.0.0.1"
        port: int = Field(9888, ge=1, le=65535, description="the MIT driver's default port")
        visa_library: str = Field("@py", description="PyVISA backend: @py (pyvisa-py) or a "
                                  "VISA library path ('' = the system's)")
        timeout_s: float = Field(2.0, gt=0, description="per-reply timeout")
        reply_header_bytes: int = Field(8, ge=0, le=64, description="bytes before each reply "
                                        "(MIT driver: 8; not publicly verified)")
        acknowledged_writes: bool = Field(True, description="the controller answers OK to each "
                                          "command line (TCP per the MIT driver; GPIB: false)")
        write_termination: str = "\r\n"
        read_termination: str = "\r\n"
        poll_interval_s: float = Field(0.005, gt=0, description="log state polling period")
        move_timeout_s: float = Field(120.0, gt=0)
        log_margin_s: float = Field(60.0, gt=0, description="wall time beyond the record")
        chunk_samples: int = Field(10_000, ge=100, le=20_000, description="log samples per read")
        reference: Literal["controller-log"] = Field(
            "controller-log", description="where the reference comes from: the controller's "
            "log (the :XLOG convention of aatest's simulator)")
        envelope: TableEnvelope = TableEnvelope()

    def __init__(self, config: Config | None, context: RigContext | None) -> None:
        self.config = config if config is not None else self.Config()
        self.context = context
        self.simulated = False
        self.identity = ""
        self._session: Any = None
        #: one exchange at a time on the session (the live status poll has its own thread)
        self._io = threading.Lock()
        cfg = self.config
        self.resource = cfg.resource or f"TCPIP::{cfg.host}::{cfg.port}::SOCKET"
        self._where = f"ACUTROL controller {self.resource}"
        #: the current step holds the table with the motor off (``motor_on: false``)
        self._motor_off = False

    # --- transport -------------------------------------------------------------------------
    def _open(self) -> None:
        import pyvisa

        self._close_session()
        cfg = self.config
        try:
            manager = pyvisa.ResourceManager(cfg.visa_library)
            session: Any = manager.open_resource(self.resource,
                                                 open_timeout=int(cfg.timeout_s * 1000))
        except Exception as exc:
            raise RigFault(f"{self._where}: cannot connect ({type(exc).__name__}: "
                           f"{' '.join(str(exc).split())})") from exc
        session.timeout = int(cfg.timeout_s * 1000)
        session.write_termination = cfg.write_termination
        session.read_termination = cfg.read_termination
        self._session = session

    def _close_session(self) -> None:
        if self._session is not None:
            try:
                self._session.close()
            except Exception as exc:  # noqa: BLE001 - closing a dead session
                log.debug("%s: close: %s", self._where, exc)
            self._session = None

    def _line(self, line: str, query: bool = False) -> str:
        """Send one command line; return its reply (``OK`` for an acknowledged write)."""
        if self._session is None:
            raise RigFault(f"{self._where}: not connected ({line})")
        expect = query or self.config.acknowledged_writes
        try:
            with self._io:  # a reply belongs to the line just written
                self._session.write(line)
                reply = self._session.read() if expect else ""
        except Exception as exc:
            self._close_session()  # a late reply must not answer the next request
            raise RigFault(f"{self._where}: no valid reply to {line!r} "
                           f"({type(exc).__name__}: {' '.join(str(exc).split())})") from exc
        reply = reply[self.config.reply_header_bytes:].strip() if expect else ""
        if reply.startswith("ERR"):
            raise RigFault(f"{self._where}: {line!r} refused: {reply[3:].strip()}")
        if expect and not query and reply != "OK":
            raise RigFault(f"{self._where}: unexpected reply {reply!r} to {line!r}")
        return reply

    def query(self, line: str) -> str:
        return self._line(line, query=True)

    def write(self, line: str) -> None:
        self._line(line)

    # --- Turntable protocol ----------------------------------------------------------------
    @property
    def serial(self) -> str | None:
        """The controller's serial number (``*IDN?``), identifying the table on certificates.

        None until :meth:`start` has identified the controller (the engine asks before and
        after start; a made-up "unknown" recorded before start would make a resumed run look
        like one on another table).
        """
        fields = self.identity.split(",")
        serial = fields[IDN_SERIAL_FIELD].strip() if len(fields) > IDN_SERIAL_FIELD else ""
        return serial or None

    def envelope(self) -> TableEnvelope:
        return self.config.envelope

    @rig_boundary
    def start(self) -> None:
        """Connect, identify, check the log path, set the user limits, close interlocks."""
        self._open()
        self.identity = self.query("*IDN?")
        self.simulated = "SIMULATOR" in self.identity.upper()
        try:
            self.query(":XLOG:STATE?")
        except RigFault as exc:
            raise RigFault(f"{self._where}: no table log (:XLOG, the reference path "
                           f"'{self.config.reference}') on this controller: {exc}") from exc
        env = self.config.envelope
        for axis, limits in ((1, env.inner), (2, env.outer)):
            for mode in ("P", "R", "S"):
                self.write(f":LIMIT:RATE {mode},{axis},{limits.rate_dps:.6g};"
                           f":LIMIT:ACCELERATION {mode},{axis},{limits.accel_dps2:.6g}")
        self.write(":INTERLOCK:RESET;:INTERLOCK:CLOSE 1;:INTERLOCK:CLOSE 2")
        log.info("%s: %s%s", self._where, self.identity, " (simulated)" if self.simulated else "")

    @rig_boundary
    def move_to(self, inner_deg: float, outer_deg: float) -> None:
        self.write(":MODE:POSITION 1;:MODE:POSITION 2")
        self.write(f":DEMAND:POSITION 1,{inner_deg:.6f};:DEMAND:POSITION 2,{outer_deg:.6f}")
        reply = self.query(":READ:POSITION? 1;POSITION? 2")
        actual = [float(v) for v in reply.split(";")]
        if max(abs(actual[0] - inner_deg), abs(actual[1] - outer_deg)) > IN_POSITION_DEG:
            raise RigFault(f"{self._where}: not in position ({reply}, demanded "
                           f"{inner_deg:g}, {outer_deg:g})")

    @rig_boundary
    def begin_motion(self, step: PlannedStep) -> None:
        """Configure the log, set the step's modes and demands (one line: they start
        together), arm the log (started by the DAQ trigger) and wait until settled.

        A static step longer than the log buffer is streamed by the DAQ: the log is then its
        head (:func:`~aatest.engine.procedure.envelope.head_step`, as many samples as the
        declared ``log_capacity_samples``), armed here before the DAQ's trigger starts the
        record, and collected by :meth:`record` afterwards.

        A static step with ``motor_on: false`` opens both interlocks before the log is armed:
        in the public command set the interlock is what switches the motor off (the MIT
        driver's shutdown, :meth:`safe_stop`); the hold then has no servo jitter and may
        drift. :meth:`end_motion` closes them again before the table is commanded.
        """
        label = step.id.replace(",", "_").replace(";", "_").replace(" ", "_")
        samples = _logged_samples(step, self.config.envelope.log_capacity_samples)
        self.write(f":XLOG:CONFIG {step.sample_rate_hz:.17g},{samples},"
                   f"{step.settle_s:.17g},{label}")
        mounting = step.mounting
        if self.simulated and (mounting.pivoted or mounting.remount != "none"):
            # the simulator's stand-in for the operator who pivots/re-mounts the unit at the
            # step's prompt; on a real table the operator does it and nothing is sent
            self.write(f":XLOG:MOUNTING {int(mounting.pivoted)},{mounting.remount}")
        modes, demands = _profile(step)
        self._motor_off = not step.motor_on
        if self._motor_off:  # validation admits motor_on: false on static steps only
            self.write(":INTERLOCK:OPEN 1;:INTERLOCK:OPEN 2")
        if modes:
            self.write(modes)
            self.write(demands)
        self.write(":XLOG:ARM")
        self._wait_state(("ARMED", "RECORDING", "DONE"), step.settle_s + self.config.move_timeout_s)

    def _wait_state(self, states: tuple[str, ...], timeout_s: float) -> str:
        deadline = time.monotonic() + timeout_s
        while True:
            state = self.query(":XLOG:STATE?")
            if state == "ERROR":
                raise RigFault(f"{self._where}: the controller's log failed")
            if state in states:
                return state
            if time.monotonic() > deadline:
                raise RigFault(f"{self._where}: log state {state}, not {'/'.join(states)} "
                               f"within {timeout_s:g} s")
            time.sleep(self.config.poll_interval_s)

    @rig_boundary
    def record(self, step: PlannedStep) -> SampledLog:
        """Wait for the log (started by the DAQ trigger) and read it channel by channel."""
        self._wait_state(("DONE",), step.samples / step.sample_rate_hz + self.config.log_margin_s)
        log_id, samples, rate_hz, _t0 = self.query(":XLOG:HEADER?").split(",")
        if int(samples) != step.samples:
            raise RigFault(f"{self._where}: log {log_id} has {samples} samples, expected "
                           f"{step.samples}")
        data = {name: self._channel(code, int(samples)) for code, name in enumerate(LOG_CHANNELS)}
        time_s = data.pop("time_s")
        return SampledLog(TABLE, float(rate_hz), time_s, data, dict(TABLE_CHANNELS))

    def _channel(self, code: int, samples: int) -> np.ndarray:
        per = self.config.chunk_samples
        parts = []
        for start in range(0, samples, per):
            count = min(per, samples - start)
            reply = self.query(f":XLOG:DATA? {code},{start},{count}")
            values = np.array(reply.split(","), dtype=np.float64)
            if values.size != count:
                raise RigFault(f"{self._where}: log channel {LOG_CHANNELS[code]} at {start}: "
                               f"{values.size} values, expected {count}")
            parts.append(values)
        return np.concatenate(parts) if parts else np.zeros(0)

    @rig_boundary
    def status(self) -> TableStatus:
        """Both axes' position (°) and rate (°/s), read in one line (``:READ:POSITION? 1;
        RATE? 1;POSITION? 2;RATE? 2``). The public command set reads no controller clock,
        so the reading is timed on the host's monotonic clock, at the middle of the exchange."""
        sent_s = time.monotonic()
        reply = self.query(STATUS_QUERY)
        time_s = (sent_s + time.monotonic()) / 2
        try:
            inner_deg, inner_dps, outer_deg, outer_dps = (float(v) for v in reply.split(";"))
        except ValueError as exc:
            raise RigFault(f"{self._where}: status reply {reply!r} to {STATUS_QUERY!r} is not "
                           "four numbers") from exc
        return TableStatus(time_s=time_s, clock="host", inner_position_deg=inner_deg,
                           inner_rate_dps=inner_dps, outer_position_deg=outer_deg,
                           outer_rate_dps=outer_dps)

    @rig_boundary
    def end_motion(self) -> None:
        """Back to position mode on both axes: the profile stops, the table holds (the
        interlocks closed first, motor on, after a step held with the motor off)."""
        if self._motor_off:
            self.write(":INTERLOCK:RESET;:INTERLOCK:CLOSE 1;:INTERLOCK:CLOSE 2")
            self._motor_off = False
        self.write(":MODE:POSITION 1;:MODE:POSITION 2")

    def safe_stop(self) -> None:
        """Modes off, interlocks open (motion stopped, motor off); never raises."""
        if self._session is None and not self.identity:
            return
        for reconnect in (self._session is None, True):
            try:
                if reconnect:
                    self._open()
                self.write(":MODE:OFF 1;:MODE:OFF 2;:INTERLOCK:OPEN 1;:INTERLOCK:OPEN 2")
                return
            except Exception as exc:  # noqa: BLE001 - a safe stop must not raise
                log.error("%s: safe stop not confirmed%s: %s", self._where,
                          " after reconnecting" if reconnect else "", exc)
            if reconnect:
                return

    def close(self) -> None:
        self._close_session()


def _logged_samples(step: PlannedStep, capacity: int) -> int:
    """The samples the table logs of ``step``: all of them, or its head when the step is a
    static record longer than the log buffer (the DAQ streams it; the envelope check refuses
    any other step beyond the capacity before anything moves)."""
    return capacity if step.kind == "static" and step.samples > capacity else step.samples


def _profile(step: PlannedStep) -> tuple[str, str]:
    """The mode line and the demand line of a step (sine amplitude A = α/(2πf)²)."""
    if step.kind == "sine":
        f_hz = float(step.frequency_hz or 0.0)
        amp = step.amplitude_deg if step.amplitude_deg is not None else (
            float(step.accel_dps2 or 0.0) / (2 * math.pi * f_hz) ** 2 if f_hz else 0.0)
        axis = AXIS["outer" if step.axis == "outer" else "inner"]
        return (f":MODE:SYNTHESIS {axis}",
                f":DEMAND:OSCILLATION {axis},{float(amp):.17g},{f_hz:.17g},0")
    if step.kind == "constant_rate":
        rate, outer = float(step.rate_dps or 0.0), float(step.outer_rate_dps or 0.0)
        if step.axis == "outer" and step.outer_rate_dps is None:
            rate, outer = 0.0, rate
        return (":MODE:RATE 1;:MODE:RATE 2",
                f":DEMAND:RATE 1,{rate:.17g};:DEMAND:RATE 2,{outer:.17g}")
    return "", ""
