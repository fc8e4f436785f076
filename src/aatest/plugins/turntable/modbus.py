"""Turntable plugin for a two-axis controller on Modbus TCP (register map: ``modbus_map``).

The driver speaks only the documented register map (``docs/modbus-register-map.md``): it
writes demands and the log configuration, issues commands through a sequence-numbered
handshake (one FC 23 transaction: write COMMAND+SEQ, read ACK+RESULT), waits on the
*controller's* clock and status bits, and downloads the table log in windows of 120 registers.
Every pymodbus error, socket error, timeout, partial frame, refused command or fault bit is
translated here, at the plugin boundary (``_call``, and
:func:`~aatest.engine.errors.rig_boundary` on every public step), into
:class:`~aatest.engine.errors.RigFault` with a one-line reason naming the controller;
:meth:`ModbusTurntable.safe_stop` then commands an emergency stop (motion stopped, motor off;
once more over a new connection when the link was reset) and never raises. Construction never
connects; :meth:`ModbusTurntable.start` does.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable
from operator import methodcaller
from typing import Literal, TypeVar

import numpy as np
from pydantic import BaseModel, ConfigDict, Field
from pymodbus.client import ModbusTcpClient
from pymodbus.exceptions import ModbusException

from aatest.engine.errors import RigFault, rig_boundary
from aatest.engine.interfaces import RigContext, TableCapabilities, TableEnvelope, TableStatus
from aatest.engine.logs import TABLE, TABLE_CHANNELS, SampledLog
from aatest.engine.steps import PlannedStep
from aatest.protocols import modbus_map as mm
from aatest.protocols.modbus_map import Command, Fault, Mode, Refusal, Reg, Status

log = logging.getLogger("aatest.turntable.modbus")
T = TypeVar("T")
#: the live status block, read in one request: controller time, then each axis's position
#: estimate and rate estimate (``Reg.CONTROLLER_TIME_S`` to ``Reg.OUTER_RATE_DPS``)
STATUS_REGISTERS = (Reg.CONTROLLER_TIME_S, Reg.INNER_POSITION_DEG, Reg.INNER_RATE_DPS,
                    Reg.OUTER_POSITION_DEG, Reg.OUTER_RATE_DPS)


class ModbusTurntable:
    """A two-axis rate table whose controller speaks the aatest Modbus map (version 1)."""

    class Config(BaseModel):
        """Connection, timing and the envelope this table is declared to have."""

        model_config = ConfigDict(extra="forbid")
        host: str = "127.0.0.1"
        port: int = Field(502, ge=1, le=65535)
        unit_id: int = Field(1, ge=0, le=247, description="Modbus unit (device) id")
        timeout_s: float = Field(1.0, gt=0, description="per-request answer timeout")
        retries: int = Field(1, ge=0, le=10, description="re-sends of an unanswered request")
        poll_interval_s: float = Field(0.005, gt=0, description="status polling period (wall)")
        move_timeout_s: float = Field(120.0, gt=0, description="wall time allowed per move")
        log_margin_s: float = Field(60.0, gt=0,
                                    description="wall time allowed beyond the record length")
        log_start: Literal["trigger", "immediate"] = "trigger"
        fp_input: int = Field(1, ge=1, le=8, description="digital input wired to the sync pulse")
        trigger_input: int = Field(2, ge=1, le=8, description="digital input wired to the trigger")
        envelope: TableEnvelope = TableEnvelope()
        encoder_counts_per_rev: int | None = Field(
            None, gt=0, description="the table's encoder counts per revolution (the register "
            "map has none): declared to the uncertainty budget")
        encoder_accuracy_arcsec: float | None = Field(
            None, ge=0, description="the encoder's position accuracy bound, arcsec")
        serial: str | None = Field(None, description="the table's serial number (the register "
                                   "map does not report one)")

    def __init__(self, config: Config | None, context: RigContext | None) -> None:
        self.config = config if config is not None else self.Config()
        self.context = context
        self._client: ModbusTcpClient | None = None
        self._seq = 0
        #: one request at a time on the link (the live status poll reads from its own thread)
        self._io = threading.Lock()
        self._where = f"Modbus controller {self.config.host}:{self.config.port}"
        #: whether a simulator answers (``Reg.SIMULATED``), known once :meth:`start` connected;
        #: a run with any simulated part is a simulation, never a calibration
        self.simulated = False
        self.identity = ""
        #: (previous log id, samples) of the head log armed in begin_motion for a streamed record
        self._head_armed: tuple[int, int] | None = None
        #: the current step holds the table with the motor off (``motor_on: false``)
        self._motor_off = False

    # --- protocol plumbing -----------------------------------------------------------------
    def _call(self, what: str, fn: Callable[[ModbusTcpClient], T]) -> T:
        """Run one request; translate pymodbus errors and exception answers into RigFault."""
        if self._client is None:
            raise RigFault(f"{self._where}: not connected ({what})")
        try:
            with self._io:
                response = fn(self._client)
        except ModbusException as exc:
            raise RigFault(f"{self._where}: no answer to {what} within "
                           f"{self.config.timeout_s:g} s ({exc.__class__.__name__})") from exc
        except OSError as exc:  # reset, refused, broken pipe, unreachable: the link is gone
            raise RigFault(f"{self._where}: connection lost during {what} "
                           f"({exc.__class__.__name__}: {exc})") from exc
        if getattr(response, "isError", lambda: False)():
            raise RigFault(f"{self._where}: {what} answered with Modbus exception "
                           f"{getattr(response, 'exception_code', '?')}")
        return response

    def _read(self, reg: Reg, count: int | None = None) -> list[int]:
        n = count if count is not None else mm.width(reg)
        response = self._call(f"read {reg.name}", lambda c: c.read_holding_registers(
            int(reg), count=n, device_id=self.config.unit_id))
        return list(response.registers)

    def _value(self, reg: Reg) -> float:
        return mm.decode(reg, self._read(reg))

    def _write(self, values: dict[Reg, float]) -> None:
        for reg, value in values.items():
            words = mm.encode(reg, value)
            request = methodcaller("write_registers", int(reg), words,
                                   device_id=self.config.unit_id)
            self._call(f"write {reg.name}", request)

    def _command(self, command: Command) -> None:
        """Issue ``command``; raise RigFault when refused (with the controller's reason)."""
        self._seq = (self._seq + 1) & 0xFFFF
        response = self._call(f"command {command.name}", lambda c: c.readwrite_registers(
            read_address=int(Reg.COMMAND_ACK), read_count=2, write_address=int(Reg.COMMAND),
            values=[int(command), self._seq], device_id=self.config.unit_id))
        ack, result = response.registers[:2]
        if ack != self._seq:
            raise RigFault(f"{self._where}: command {command.name} not acknowledged "
                           f"(ack {ack}, sent {self._seq})")
        if result != Refusal.ACCEPTED:
            reason = Refusal(result).name if result in Refusal._value2member_map_ else str(result)
            detail = self._fault_text() if result == Refusal.FAULT_ACTIVE else ""
            raise RigFault(f"{self._where}: command {command.name} refused: {reason}{detail}")

    def _fault_text(self) -> str:
        fault = Fault(int(self._value(Reg.FAULT)))
        names = "|".join(f.name or "?" for f in Fault if f in fault) or "none"
        return f" (fault bits {names}, word 0x{int(fault):04x})"

    def _status(self) -> Status:
        status = Status(int(self._value(Reg.STATUS)))
        if Status.FAULT in status:
            raise RigFault(f"{self._where}: controller fault{self._fault_text()}; "
                           "motion stopped, motor off")
        return status

    def _wait(self, what: str, done: Callable[[Status], bool], timeout_s: float) -> None:
        """Poll the status word until ``done``; fault bits and the wall timeout raise."""
        deadline = time.monotonic() + timeout_s
        while not done(self._status()):
            if time.monotonic() > deadline:
                raise RigFault(f"{self._where}: {what} not reached within {timeout_s:g} s")
            time.sleep(self.config.poll_interval_s)

    # --- Turntable protocol ----------------------------------------------------------------
    def envelope(self) -> TableEnvelope:
        """The declared envelope (checked against the controller's limits in :meth:`start`)."""
        return self.config.envelope

    def capabilities(self) -> TableCapabilities:
        """What the rig file declares of this table (the register map reports no encoder or
        serial), its trigger input when the log starts on it, and its freeze-pulse latch
        (every log carries ``fp_latch_s``, the map's pulse latch)."""
        cfg = self.config
        return TableCapabilities(encoder_resolution_counts_per_rev=cfg.encoder_counts_per_rev,
                                 encoder_accuracy_arcsec=cfg.encoder_accuracy_arcsec,
                                 trigger_input=cfg.log_start == "trigger", pulse_latch=True,
                                 model=f"Modbus controller, register map {mm.MAP_VERSION}",
                                 serial=cfg.serial)

    @rig_boundary
    def start(self) -> None:
        """Connect, check the map version, read the identification (``simulated``: a
        simulator answers) and the limits, set the declared envelope as the controller's user
        limits (it then refuses anything beyond it too), configure the freeze-pulse and
        trigger inputs, clear faults, motor on."""
        cfg = self.config
        self._connect()
        version = int(self._value(Reg.MAP_VERSION))
        if version != mm.MAP_VERSION:
            raise RigFault(f"{self._where}: register map version {version}, driver speaks "
                           f"{mm.MAP_VERSION}")
        self.simulated = int(self._value(Reg.SIMULATED)) == 1
        self.identity = mm.decode_label(self._read(Reg.IDENTITY, mm.IDENTITY_REGISTERS))
        self._check_limits()
        env = cfg.envelope
        self._write({Reg.INNER_RATE_USER_LIMIT_DPS: env.inner.rate_dps,
                     Reg.INNER_ACCEL_USER_LIMIT_DPS2: env.inner.accel_dps2,
                     Reg.OUTER_RATE_USER_LIMIT_DPS: env.outer.rate_dps,
                     Reg.OUTER_ACCEL_USER_LIMIT_DPS2: env.outer.accel_dps2})
        self._command(Command.CLEAR_FAULTS)
        start = mm.LogStart.TRIGGER if cfg.log_start == "trigger" else mm.LogStart.IMMEDIATE
        self._write({Reg.FP_INPUT: cfg.fp_input, Reg.FP_EDGE: mm.Edge.BOTH,
                     Reg.TRIGGER_INPUT: cfg.trigger_input, Reg.TRIGGER_EDGE: mm.Edge.RISING,
                     Reg.LOG_START: start})
        self._command(Command.MOTOR_ON)
        status = self._status()
        if Status.INTERLOCK_CLOSED not in status:
            raise RigFault(f"{self._where}: safety interlock open; close it and retry")

    def _connect(self) -> None:
        """(Re)open the TCP connection; RigFault when the controller cannot be reached."""
        cfg = self.config
        if self._client is not None:
            self._client.close()
        self._client = ModbusTcpClient(cfg.host, port=cfg.port, timeout=cfg.timeout_s,
                                       retries=cfg.retries, reconnect_delay=0)
        try:
            connected = self._client.connect()
        except (OSError, ModbusException) as exc:
            connected, reason = False, str(exc)
        else:
            reason = "connection refused or host unreachable"
        if not connected:
            raise RigFault(f"{self._where}: cannot connect ({reason})")

    def _check_limits(self) -> None:
        """The declared envelope must lie inside the controller's factory limits."""
        env = self.config.envelope
        pairs = ((env.inner.rate_dps, Reg.INNER_RATE_LIMIT_DPS),
                 (env.inner.accel_dps2, Reg.INNER_ACCEL_LIMIT_DPS2),
                 (env.outer.rate_dps, Reg.OUTER_RATE_LIMIT_DPS),
                 (env.outer.accel_dps2, Reg.OUTER_ACCEL_LIMIT_DPS2),
                 (env.max_log_rate_hz, Reg.LOG_RATE_MAX_HZ))
        for declared, reg in pairs:
            actual = self._value(reg)
            if declared > actual * (1 + 1e-6):
                raise RigFault(f"{self._where}: declared envelope {reg.name.lower()} "
                               f"{declared:g} exceeds the controller's {actual:g}; "
                               "fix the rig file")

    @rig_boundary
    def move_to(self, inner_deg: float, outer_deg: float) -> None:
        self._write({Reg.MODE: Mode.POSITION, Reg.INNER_POSITION_DEMAND_DEG: inner_deg,
                     Reg.OUTER_POSITION_DEMAND_DEG: outer_deg})
        self._command(Command.START_MOTION)
        self._wait("in position", lambda s: Status.IN_POSITION in s and Status.MOVING not in s,
                   self.config.move_timeout_s)

    @rig_boundary
    def begin_motion(self, step: PlannedStep) -> None:
        """Write the log configuration, the settling time and the step's demands, start,
        and wait until the controller reports the profile settled.

        A step with ``motor_on: false`` (static only: the twin refuses motion without the
        motor) switches the motor off before it starts, as the simulated table does;
        :meth:`end_motion` switches it on again.

        A static step longer than the log buffer is streamed by the DAQ: the log is then its
        head (:func:`~aatest.engine.procedure.envelope.head_step`), armed here, before the
        DAQ's trigger starts the record (:meth:`record` collects it afterwards).
        """
        head = self._head_samples(step)
        writes: dict[Reg, float] = {Reg.LOG_SAMPLES: head or step.samples,
                                    Reg.LOG_RATE_HZ: step.sample_rate_hz,
                                    Reg.SETTLE_S: step.settle_s}
        writes.update(_demands(step))
        self._write(writes)
        self._call("write LOG_LABEL", lambda c: c.write_registers(
            int(Reg.LOG_LABEL), mm.encode_label(step.id), device_id=self.config.unit_id))
        self._motor_off = not step.motor_on
        if self._motor_off:  # a static step at rest without the servo's jitter (it may drift)
            self._command(Command.MOTOR_OFF)
        self._command(Command.START_MOTION)
        self._wait("settled", lambda s: Status.SETTLED in s,
                   step.settle_s + self.config.move_timeout_s)
        self._head_armed = None
        if head:
            previous = int(self._value(Reg.LOG_ID))
            self._command(Command.ARM_LOG)
            self._head_armed = (previous, head)

    def _head_samples(self, step: PlannedStep) -> int:
        """The head's length when ``step`` is a static record longer than the log buffer
        (the DAQ streams it), else 0."""
        capacity = self.config.envelope.log_capacity_samples
        return capacity if step.kind == "static" and step.samples > capacity else 0

    @rig_boundary
    def record(self, step: PlannedStep) -> SampledLog:
        """Arm the log (started by the DAQ trigger) unless begin_motion armed this head
        already, wait for it, download it."""
        armed, self._head_armed = self._head_armed, None
        if armed is not None and armed[1] == step.samples:
            previous = armed[0]
        else:
            previous = int(self._value(Reg.LOG_ID))
            self._command(Command.ARM_LOG)
        record_s = step.samples / step.sample_rate_hz
        self._wait("log complete", lambda s: Status.LOG_DONE in s,
                   record_s + self.config.log_margin_s)
        log_id, samples = int(self._value(Reg.LOG_ID)), int(self._value(Reg.LOG_SAMPLES_DONE))
        if log_id == previous or samples != step.samples:
            raise RigFault(f"{self._where}: log {log_id} has {samples} samples, expected a new "
                           f"log of {step.samples}")
        return self._download(samples, self._value(Reg.LOG_RATE_DONE_HZ))

    def _download(self, samples: int, rate_hz: float) -> SampledLog:
        data = {c.name: self._download_channel(c, samples) for c in mm.LOG_CHANNELS}
        time_s = data.pop("time_s")
        data["sync_pulse"] = data["sync_pulse"].astype(np.float64)
        return SampledLog(TABLE, rate_hz, time_s, {c: data[c] for c in TABLE_CHANNELS},
                          dict(TABLE_CHANNELS))

    def _download_channel(self, channel: mm.LogChannel, samples: int) -> np.ndarray:
        """One channel, window by window (one FC 23 per window: select and read)."""
        per = channel.samples_per_window
        parts = []
        for start in range(0, samples, per):
            select = [channel.code, 0, *mm.encode(Reg.WINDOW_START, start)]
            request = methodcaller(
                "readwrite_registers", read_address=int(Reg.WINDOW),
                read_count=mm.WINDOW_REGISTERS, write_address=int(Reg.WINDOW_CHANNEL),
                values=select, device_id=self.config.unit_id)
            response = self._call(f"log window {channel.name}@{start}", request)
            parts.append(mm.decode_channel_window(response.registers, channel,
                                                  min(per, samples - start)))
        return np.concatenate(parts) if parts else np.zeros(0)

    @rig_boundary
    def status(self) -> TableStatus:
        """The live status block in one read (registers 6–21, one consistent snapshot):
        controller time (s), each axis's position (°) and rate (°/s) estimates."""
        first = STATUS_REGISTERS[0]
        last = STATUS_REGISTERS[-1]
        words = self._read(first, int(last) + mm.width(last) - int(first))
        time_s, inner_deg, inner_dps, outer_deg, outer_dps = (
            mm.decode(reg, words[reg - first: reg - first + mm.width(reg)])
            for reg in STATUS_REGISTERS)
        return TableStatus(time_s=time_s, clock="controller", inner_position_deg=inner_deg,
                           inner_rate_dps=inner_dps, outer_position_deg=outer_deg,
                           outer_rate_dps=outer_dps)

    @rig_boundary
    def end_motion(self) -> None:
        """Stop the profile; the controller returns to its start position (the motor on
        again after a step recorded with it off)."""
        if self._motor_off:  # the servo back on first: it returns the table to the start
            self._command(Command.MOTOR_ON)
            self._motor_off = False
        self._command(Command.STOP)
        self._wait("back at the start position",
                   lambda s: Status.IN_POSITION in s and Status.MOVING not in s,
                   self.config.move_timeout_s)

    def safe_stop(self) -> None:
        """Emergency stop (motion stopped, motor off); never raises, idempotent.

        When the link was reset, the command is sent once more over a new connection; a
        controller that cannot be reached at all is logged (each attempt bounded by
        ``timeout_s``) and left to its own watchdog.
        """
        if self._client is None:
            return
        for reconnect in (False, True):  # a reset link is reopened once: the table must stop
            try:
                if reconnect:
                    self._connect()
                self._command(Command.EMERGENCY_STOP)
                return
            except Exception as exc:  # noqa: BLE001 - a safe stop must not raise
                log.error("%s: emergency stop not confirmed%s: %s", self._where,
                          " after reconnecting" if reconnect else "", exc)

    def close(self) -> None:
        if self._client is not None:
            self._client.close()
            self._client = None


def _demands(step: PlannedStep) -> dict[Reg, float]:
    """Mode and demand registers for a step (sine amplitude A = α/(2πf)², docs/method.md §3)."""
    zero: dict[Reg, float] = {Reg.INNER_RATE_DEMAND_DPS: 0.0, Reg.OUTER_RATE_DEMAND_DPS: 0.0,
                              Reg.INNER_SINE_AMPLITUDE_DEG: 0.0, Reg.INNER_SINE_FREQUENCY_HZ: 0.0,
                              Reg.OUTER_SINE_AMPLITUDE_DEG: 0.0, Reg.OUTER_SINE_FREQUENCY_HZ: 0.0}
    if step.kind == "sine":
        f_hz = float(step.frequency_hz or 0.0)
        amp = step.amplitude_deg if step.amplitude_deg is not None else (
            float(step.accel_dps2 or 0.0) / (2 * math.pi * f_hz) ** 2 if f_hz else 0.0)
        axis = "OUTER" if step.axis == "outer" else "INNER"
        zero[Reg[f"{axis}_SINE_AMPLITUDE_DEG"]] = float(amp)
        zero[Reg[f"{axis}_SINE_FREQUENCY_HZ"]] = f_hz
        return {Reg.MODE: Mode.SINE, **zero}
    if step.kind == "constant_rate":
        rate, outer = float(step.rate_dps or 0.0), float(step.outer_rate_dps or 0.0)
        if step.axis == "outer" and step.outer_rate_dps is None:
            rate, outer = 0.0, rate
        zero[Reg.INNER_RATE_DEMAND_DPS], zero[Reg.OUTER_RATE_DEMAND_DPS] = rate, outer
        return {Reg.MODE: Mode.RATE, **zero}
    return {Reg.MODE: Mode.HOLD, **zero}

