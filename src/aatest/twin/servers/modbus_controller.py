"""The simulated turntable controller behind the Modbus register map: the twin on a real peer.

:class:`SimController` owns one digital twin (:class:`aatest.twin.world.World`) and
turns register writes into the same World calls the in-process simulated plugins make
(move, begin motion, start DAQ, synthesise, end motion), so a driver talking Modbus to it is
exercised against the same physics. Its clock is the World's virtual lab time, advanced only
by events (a move, the settling time, a record, the return), never by the wall clock: a 70 s
record does not take 70 s, and the same seed and commands give the logs the in-process
simulated rig records (up to the map's f32 channels). The simulated CAN logger
(:mod:`aatest.twin.servers.can_sim`) starts the DAQ through :meth:`SimController.daq_start`
and receives the DAQ log of every record through ``on_daq_log``: table log and sensor log
come from one twin. A timed record of the logger (:meth:`SimController.daq_stream`) is
streamed from the World chunk by chunk instead, and the armed table log is then its head
(the table's log buffer, as long as it holds), made as the in-process simulated table makes it.

Fault injection (:class:`FaultInjection`) lets tests make the controller set a fault bit or stop
answering when a record starts, answer slowly, or stop answering from a given command on;
:meth:`SimController.recover` brings it back (the operator fixed the rig).
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from aatest.engine.errors import EnvelopeRefused
from aatest.engine.logs import SampledLog
from aatest.engine.steps import PlannedStep
from aatest.protocols import modbus_map as mm
from aatest.protocols.modbus_map import Command, Fault, Mode, Refusal, Reg, Status
from aatest.twin.model import RigModel
from aatest.twin.servers.timed_record import start_timed_record, stream_after_first_chunk
from aatest.twin.world import World

log = logging.getLogger("aatest.sim.modbus")

DaqLogSink = Callable[[SampledLog], None]
#: registers past this address hold no live status
_LIVE_END = int(Reg.MODE)
#: no fault bit set (an IntFlag value, immutable: safe as a dataclass default)
NO_FAULT = Fault(0)
#: what ``Reg.IDENTITY`` answers (``Reg.SIMULATED`` is 1): no physical table is behind it
SIMULATOR_IDENTITY = "aatest sim-server (digital twin)"


@dataclass
class FaultInjection:
    """Faults the simulated controller produces on purpose (tests only; all bounded)."""

    #: fault bits set the moment a record starts (motion stops, motor off)
    fault_on_record: Fault = NO_FAULT
    #: stop answering the moment a record starts (a controller dying mid-step)
    hang_on_record: bool = False
    #: the record-triggered faults above hit every record, or only this one (1 = first)
    record_number: int | None = None
    #: every answer is delayed this long (wall seconds)
    response_delay_s: float = 0.0
    #: from this command on the controller stops answering (for ``hang_s`` wall seconds)
    hang_on_command: Command | None = None
    hang_s: float = 20.0


@dataclass
class _Record:
    """The completed (or running) log of one step."""

    log_id: int
    table: SampledLog | None = None
    error: str | None = None
    #: the table log of a streamed record: its head, no DAQ log for the CAN logger
    head: PlannedStep | None = None


class SimController:
    """Register file + state machine of a two-axis controller driving a twin World.

    Parameters
    ----------
    model
        Twin model (see :func:`aatest.twin.api.realistic_rig_model`).
    seed
        Seed of the World; the same seed and call sequence give the same logs.
    faults
        Optional fault injection.
    """

    def __init__(self, model: RigModel, seed: int = 0,
                 faults: FaultInjection | None = None) -> None:
        self.world = World(model, seed)
        self.faults = faults or FaultInjection()
        self.hanging = False
        self.on_daq_log: DaqLogSink | None = None
        self._lock = threading.RLock()
        self._regs = np.zeros(mm.REGISTER_COUNT, dtype=np.int64)
        self._status = Status.READY | Status.INTERLOCK_CLOSED | Status.IN_POSITION
        self._fault = Fault(0)
        self._mode = Mode.HOLD
        self._moving = False
        self._daq_started = False
        #: the DAQ streams this step's record (a timed record of the CAN logger)
        self._streamed = False
        self._armed = False
        self._record: _Record | None = None
        self._log_count = 0
        self._records_started = 0
        self._init_registers(model)

    def pose_as_hardware(self, identity: str) -> None:
        """Answer ``Reg.SIMULATED`` = 0 and ``identity``, like a physical controller (tests of
        the real-rig path only: the command line offers no way to do this)."""
        with self._lock:
            self._put(Reg.SIMULATED, 0)
            self._regs[Reg.IDENTITY: Reg.IDENTITY + mm.IDENTITY_REGISTERS] = mm.encode_label(
                identity, mm.IDENTITY_REGISTERS)

    def recover(self) -> None:
        """Remove injected faults and answer again (latched fault bits stay until cleared)."""
        with self._lock:
            self.faults = FaultInjection()
            self.hanging = False

    # --- registers -------------------------------------------------------------------------
    def _put(self, reg: Reg, value: float) -> None:
        words = mm.encode(reg, value)
        self._regs[reg: reg + len(words)] = words

    def _get(self, reg: Reg) -> float:
        return mm.decode(reg, self._regs[reg: reg + mm.width(reg)].tolist())

    def _init_registers(self, model: RigModel) -> None:
        table = model.table
        for reg, value in ((Reg.MAP_VERSION, mm.MAP_VERSION), (Reg.AXES, 2),
                           (Reg.LOG_CAPACITY, table.log_capacity_samples),
                           (Reg.LOG_RATE_MAX_HZ, table.log_rate_hz),
                           (Reg.INNER_RATE_LIMIT_DPS, table.inner.rate_limit_dps),
                           (Reg.INNER_ACCEL_LIMIT_DPS2, table.inner.accel_limit_dps2),
                           (Reg.OUTER_RATE_LIMIT_DPS, table.outer.rate_limit_dps),
                           (Reg.OUTER_ACCEL_LIMIT_DPS2, table.outer.accel_limit_dps2),
                           (Reg.MAX_FREQUENCY_HZ, 10.0), (Reg.FP_INPUT, 1), (Reg.TRIGGER_INPUT, 2),
                           (Reg.LOG_START, mm.LogStart.TRIGGER),
                           (Reg.LOG_RATE_HZ, table.log_rate_hz), (Reg.SIMULATED, 1)):
            self._put(reg, value)
        # the identification a driver reads at start: a run on this server is a simulation
        identity = mm.encode_label(SIMULATOR_IDENTITY, mm.IDENTITY_REGISTERS)
        self._regs[Reg.IDENTITY: Reg.IDENTITY + mm.IDENTITY_REGISTERS] = identity

    def read(self, address: int, count: int) -> list[int] | None:
        """Register values, or ``None`` for an address outside the map."""
        if address < 0 or address + count > mm.REGISTER_COUNT:
            return None
        with self._lock:
            if address < _LIVE_END:  # live status is computed on demand, not per window read
                self._refresh()
            return self._regs[address: address + count].tolist()

    def write(self, address: int, values: list[int]) -> bool:
        """Store values and act on commands; ``False`` for read-only or unknown addresses."""
        span = range(address, address + len(values))
        if address < 0 or span.stop > mm.REGISTER_COUNT or any(
                span.start < ro.stop and ro.start < span.stop for ro in mm.READ_ONLY):
            return False
        with self._lock:
            self._regs[address: span.stop] = values
            if Reg.WINDOW_CHANNEL in span or Reg.WINDOW_START in span:
                self._fill_window()
            if Reg.COMMAND in span and Reg.COMMAND_SEQ in span:
                self._execute(Command(values[Reg.COMMAND - address])
                              if values[Reg.COMMAND - address] in Command._value2member_map_
                              else None)
        return True

    # --- clock and live status -------------------------------------------------------------
    def now_s(self) -> float:
        """Controller clock (s): the World's lab time."""
        return float(self.world.lab_time_s)

    def _refresh(self) -> None:
        status = self._status & ~(Status.MOTOR_ON | Status.MOVING | Status.FAULT)
        status |= Status.MOTOR_ON if self.world.motor_on else Status(0)
        status |= Status.MOVING if self._moving else Status(0)
        status |= Status.FAULT if self._fault else Status(0)
        self._status = status
        self._put(Reg.STATUS, int(status))
        self._put(Reg.FAULT, int(self._fault))
        self._put(Reg.MODE_ACTIVE, int(self._mode))
        self._put(Reg.HEARTBEAT, int(self._get(Reg.HEARTBEAT)) + 1)
        table = self.world.table_state()  # the twin's motion at the controller clock
        self._put(Reg.CONTROLLER_TIME_S, table.time_s)
        self._put(Reg.INNER_POSITION_DEG, table.inner_deg)
        self._put(Reg.INNER_RATE_DPS, table.inner_dps)
        self._put(Reg.OUTER_POSITION_DEG, table.outer_deg)
        self._put(Reg.OUTER_RATE_DPS, table.outer_dps)
        recorded = self._record.table if self._record and self._record.table else None
        self._put(Reg.LOG_RECORDED, len(recorded) if recorded is not None else 0)

    # --- commands --------------------------------------------------------------------------
    def _execute(self, command: Command | None) -> None:
        if self.faults.hang_on_command is not None and command == self.faults.hang_on_command:
            self.hanging = True
        refusal = self._dispatch(command)
        self._put(Reg.COMMAND_ACK, self._get(Reg.COMMAND_SEQ))
        self._put(Reg.COMMAND_RESULT, int(refusal))
        if refusal:
            self._put(Reg.REFUSAL, int(refusal))
            log.info("command %s refused: %s", command, refusal.name)

    def _dispatch(self, command: Command | None) -> Refusal:
        """Carry out one command; its refusal code answers it (``ACCEPTED`` when done).

        Stopping, clearing faults and aborting a log are obeyed even with a fault active, as
        a real controller must; anything that moves or records is refused while a fault bit
        is set.
        """
        if command is None:
            return Refusal.UNKNOWN_COMMAND
        if command in (Command.EMERGENCY_STOP, Command.MOTOR_OFF, Command.STOP,
                       Command.CLEAR_FAULTS, Command.ABORT_LOG):
            self._obey_in_any_state(command)
            return Refusal.ACCEPTED
        if self._fault:
            return Refusal.FAULT_ACTIVE
        handlers = {Command.MOTOR_ON: self._motor_on, Command.START_MOTION: self._start_motion,
                    Command.ARM_LOG: self._arm_log}
        handler = handlers.get(command)
        return handler() if handler is not None else Refusal.UNKNOWN_COMMAND

    def _obey_in_any_state(self, command: Command) -> None:
        """Stop (motor off unless plain STOP), clear the faults, or abort the armed log."""
        if command == Command.CLEAR_FAULTS:
            self._fault = NO_FAULT
        elif command == Command.ABORT_LOG:
            self._armed, self._record = False, None
            self._status &= ~(Status.LOG_ARMED | Status.LOG_RECORDING | Status.LOG_DONE)
        else:
            self._stop(motor_off=command != Command.STOP)

    def _motor_on(self) -> Refusal:
        self.world.motor_on = True
        return Refusal.ACCEPTED

    def _stop(self, motor_off: bool) -> None:
        """End the profile and return to its start position (hold there); motor off if asked."""
        self.world.end_motion()
        self._moving, self._mode = False, Mode.HOLD
        self._armed = False
        if motor_off:
            self.world.motor_on = False
        self._status = (self._status | Status.IN_POSITION) & ~Status.SETTLED

    def _planned_step(self, mode: Mode) -> PlannedStep:
        """The step the registers describe, for the World (log config taken as in force)."""
        label = self._label()
        common = {"id": label, "samples": int(self._get(Reg.LOG_SAMPLES)),
                  "sample_rate_hz": self._get(Reg.LOG_RATE_HZ), "settle_s": self._get(Reg.SETTLE_S),
                  "inner_deg": self.world.inner_deg, "outer_deg": self.world.outer_deg}
        if mode == Mode.SINE:
            axis = "outer" if self._get(Reg.OUTER_SINE_AMPLITUDE_DEG) else "inner"
            return PlannedStep(kind="sine", axis=axis, **common,
                               amplitude_deg=self._get(Reg[f"{axis.upper()}_SINE_AMPLITUDE_DEG"]),
                               frequency_hz=self._get(Reg[f"{axis.upper()}_SINE_FREQUENCY_HZ"]))
        if mode == Mode.RATE:
            return PlannedStep(kind="constant_rate", axis="inner", **common,
                               rate_dps=self._get(Reg.INNER_RATE_DEMAND_DPS),
                               outer_rate_dps=self._get(Reg.OUTER_RATE_DEMAND_DPS))
        return PlannedStep(kind="static", **common)

    def _label(self) -> str:
        """The driver-written log label (the step id), else a running log number."""
        words = self._regs[Reg.LOG_LABEL: Reg.LOG_LABEL + mm.LABEL_REGISTERS].tolist()
        return mm.decode_label(words) or f"log{self._log_count + 1:05d}"

    def _start_motion(self) -> Refusal:
        code = int(self._get(Reg.MODE))
        if code not in Mode._value2member_map_:
            return Refusal.UNKNOWN_COMMAND
        mode = Mode(code)
        if not self.world.motor_on and mode != Mode.HOLD:  # holding at rest needs no motor
            return Refusal.MOTOR_OFF
        refusal = self._check_user_limits(mode)
        if refusal:
            return refusal
        self._status &= ~(Status.SETTLED | Status.LOG_ARMED | Status.LOG_RECORDING
                          | Status.LOG_DONE | Status.TRIGGER_SEEN)
        self._daq_started = self._armed = self._streamed = False
        if mode == Mode.POSITION:
            self.world.move_to(self._get(Reg.INNER_POSITION_DEMAND_DEG),
                               self._get(Reg.OUTER_POSITION_DEMAND_DEG))
            self._mode, self._moving = mode, False
            self._status |= Status.IN_POSITION
            return Refusal.ACCEPTED
        try:  # the World runs the profile from its start position and settles SETTLE_S
            self.world.begin_motion(self._planned_step(mode))
        except EnvelopeRefused as exc:
            return Refusal.ACCEL_LIMIT if "acceleration" in str(exc) else Refusal.RATE_LIMIT
        self._mode, self._moving = mode, mode in (Mode.RATE, Mode.SINE)
        self._status = (self._status & ~Status.IN_POSITION) | Status.SETTLED
        return Refusal.ACCEPTED

    def _check_user_limits(self, mode: Mode) -> Refusal:
        """Refuse demands beyond the user limits (0 = factory limit only; the World checks
        the factory limits itself)."""
        for axis in ("INNER", "OUTER"):
            amp = self._get(Reg[f"{axis}_SINE_AMPLITUDE_DEG"]) if mode == Mode.SINE else 0.0
            omega = 2 * np.pi * self._get(Reg[f"{axis}_SINE_FREQUENCY_HZ"])
            rate = abs(self._get(Reg[f"{axis}_RATE_DEMAND_DPS"])) if mode == Mode.RATE else 0.0
            peak_rate, peak_accel = rate + abs(amp) * omega, abs(amp) * omega ** 2
            rate_limit = self._get(Reg[f"{axis}_RATE_USER_LIMIT_DPS"])
            accel_limit = self._get(Reg[f"{axis}_ACCEL_USER_LIMIT_DPS2"])
            if rate_limit and peak_rate > rate_limit * (1 + 1e-6):
                return Refusal.RATE_LIMIT
            if accel_limit and peak_accel > accel_limit * (1 + 1e-6):
                return Refusal.ACCEL_LIMIT
        return Refusal.ACCEPTED

    def _arm_log(self) -> Refusal:
        samples, rate_hz = int(self._get(Reg.LOG_SAMPLES)), self._get(Reg.LOG_RATE_HZ)
        if not 0 < samples <= int(self._get(Reg.LOG_CAPACITY)):
            return Refusal.LOG_CAPACITY
        if not 0 < rate_hz <= self._get(Reg.LOG_RATE_MAX_HZ):
            return Refusal.LOG_RATE
        if self._record is not None and self._record.table is None and self._record.error is None:
            return Refusal.BUSY
        self._record, self._armed = None, True
        self._status = (self._status | Status.LOG_ARMED) & ~Status.LOG_DONE
        if int(self._get(Reg.LOG_START)) == mm.LogStart.IMMEDIATE:
            self.world.start_daq()
            self._daq_started = True
        self._maybe_record()
        return Refusal.ACCEPTED

    # --- DAQ trigger and synthesis ---------------------------------------------------------
    def daq_start(self) -> None:
        """The DAQ started logging: its trigger line goes high (called by the CAN logger)."""
        with self._lock:
            if self._fault or self._daq_started:
                return
            self.world.start_daq()
            self._daq_started = True
            self._status |= Status.TRIGGER_SEEN
            self._maybe_record()

    def daq_stream(self, samples: int) -> Iterator[SampledLog]:
        """The DAQ started a timed record of ``samples`` after its trigger (called by the CAN
        logger): the trigger line goes high, the World's record takes that length, and its DAQ
        log is returned lazily in chunks (one in memory at a time). The armed table log is the
        record's head, made after the stream's first chunk as the in-process table makes it
        after the DAQ's (same random streams).

        Raises
        ------
        ValueError
            A fault is active, no step is in motion, or a record already runs (the logger
            refuses the timed record).
        """
        with self._lock:
            if self._fault or self._daq_started:
                raise ValueError("controller fault active or a record already running")
            start_timed_record(self.world, samples)
            self._daq_started = self._streamed = True
            self._status |= Status.TRIGGER_SEEN
        return stream_after_first_chunk(self.world, self._record_under_lock)

    def _record_under_lock(self) -> None:
        with self._lock:
            self._maybe_record()

    def _maybe_record(self) -> None:
        if not (self._armed and self._daq_started) or self._record is not None:
            return
        self._records_started += 1
        if self.faults.record_number in (None, self._records_started):
            self.hanging = self.hanging or self.faults.hang_on_record
            if self.faults.fault_on_record:
                self._trip(self.faults.fault_on_record)
                return
        self._armed = False
        head = self._planned_step(Mode.HOLD) if self._streamed else None
        self._record = _Record(self._log_count + 1, head=head)
        self._status = (self._status | Status.LOG_RECORDING) & ~Status.LOG_ARMED
        threading.Thread(target=self._synthesise, args=(self._record,), daemon=True,
                         name="sim-controller-record").start()

    def _trip(self, fault: Fault) -> None:
        self._fault |= fault
        self._stop(motor_off=True)
        log.warning("controller fault %s: motion stopped, motor off", fault)

    def _synthesise(self, record: _Record) -> None:
        """Run the twin for the armed record (worker thread: the server keeps answering)."""
        try:
            if record.head is not None:
                table, daq = self.world.snapshot_log(record.head), None
            else:
                result = self.world.result()
                table, daq = result.table, result.daq
        except Exception as exc:  # noqa: BLE001 - reported through the fault word
            log.error("twin synthesis failed: %s: %s", type(exc).__name__, exc)
            with self._lock:
                record.error = str(exc)
                self._trip(Fault.SERVO_ERROR)
            return
        with self._lock:
            if self._record is not record:
                return
            if self.on_daq_log is not None and daq is not None:  # queued before LOG_DONE:
                self.on_daq_log(daq)  # the stream precedes STOP
            record.table = table
            self._log_count = record.log_id
            self._publish_header(table, record.log_id)

    def _publish_header(self, table: SampledLog, log_id: int) -> None:
        self._put(Reg.LOG_ID, log_id)
        self._put(Reg.LOG_SAMPLES_DONE, len(table))
        self._put(Reg.LOG_T0_S, float(table.time_s[0]))
        self._put(Reg.LOG_RATE_DONE_HZ, table.sample_rate_hz)
        self._status = (self._status | Status.LOG_DONE) & ~Status.LOG_RECORDING

    def _fill_window(self) -> None:
        """Put the selected channel's samples into ``Reg.WINDOW``."""
        code, start = int(self._get(Reg.WINDOW_CHANNEL)), int(self._get(Reg.WINDOW_START))
        channel = mm.CHANNEL_BY_CODE.get(code)
        table = self._record.table if self._record is not None else None
        regs = [0] * mm.WINDOW_REGISTERS
        if channel is not None and table is not None and start < len(table):
            values = table.time_s if channel.name == "time_s" else table[channel.name]
            regs = mm.encode_channel_window(values, channel, start)
        self._regs[Reg.WINDOW: Reg.WINDOW + mm.WINDOW_REGISTERS] = regs
