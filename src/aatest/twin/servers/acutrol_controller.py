"""A simulated ACUTROL-class two-axis table controller on top of the twin.

:class:`AcutrolController` carries out parsed commands (:mod:`acutrol_parse`) on a
:class:`~aatest.twin.world.World`, the same calls the in-process ``sim`` table makes: a position
demand moves, a rate demand (rate mode) or an oscillation demand (synthesis mode) starts the
profile and settles, a mode change stops it (back to the start position), an open interlock
switches the motor off (``:XLOG:ARM`` then holds the table still without the servo, a
``motor_on: false`` static step; any motion stays refused). Every demand is checked against
the mode's rate and acceleration limits (``:LIMIT:RATE``/``:LIMIT:ACCELERATION``) and the
twin's own factory limits, and refused with a SCPI error (-222 data out of range, -221
settings conflict) otherwise. Errors go to an error queue (``:SYSTEM:ERROR?``, ``*STB?`` bit 2).

The table log is a simulator-side convention (``:XLOG:…``, not in the public command set; a
real controller's own logging path differs, docs/driver-acutrol.md): ``:XLOG:CONFIG rate,
samples,settle,label`` sets it up, ``:XLOG:ARM`` arms it (starting a static hold if no profile
runs), the DAQ trigger (the simulated CAN logger's ``daq_start``) starts it, ``:XLOG:STATE?``
tells IDLE/ARMED/RECORDING/DONE/ERROR, ``:XLOG:HEADER?`` gives ``id,samples,rate,t0`` and
``:XLOG:DATA? channel,start,count`` returns values of one channel as comma-separated decimals
with 17 significant digits (float64 round trip). A timed record of the CAN logger
(:meth:`AcutrolController.daq_stream`, a static record longer than the table's log) is
streamed from the World chunk by chunk; the armed log is then its head (the samples
``:XLOG:CONFIG`` asked for, at most the log's capacity), made as the in-process table makes
it. ``:XLOG:MOUNTING pivoted,remount`` (after ``:XLOG:CONFIG``, before the demands) stands
in for the operator: it pivots and re-mounts the twin's sensor unit for that log as a step's
operator prompt says (``pivoted`` 0|1, ``remount`` none|sensors|block|both), so a pivoted
procedure exercises the twin as the in-process ``sim`` table does; a new ``:XLOG:CONFIG`` is
back to the original mounting, not re-mounted.
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import get_args

import numpy as np

from aatest.engine.errors import EnvelopeRefused
from aatest.engine.logs import TABLE_CHANNELS, SampledLog
from aatest.engine.steps import Mounting, PlannedStep, Remount
from aatest.rig_defaults import LOG_RATE_HZ
from aatest.twin.servers.acutrol_parse import Command, CommandError, axis_of, numbers
from aatest.twin.servers.timed_record import start_timed_record, stream_after_first_chunk
from aatest.twin.world import World

log = logging.getLogger("aatest.sim.acutrol")
AXES = {1: "inner", 2: "outer"}
MODE_LETTERS = {"POSITION": "P", "RATE": "R", "ABSRATE": "A", "SYNTHESIS": "S", "OFF": "O"}
#: log channels in ``:XLOG:DATA?`` numbering (0 = time)
LOG_CHANNELS = ("time_s", *TABLE_CHANNELS)
DATA_MAX_COUNT = 20_000
#: ``:XLOG:CONFIG rate,samples,settle,label``: the label's position
LABEL_ARG = 3
#: ``:XLOG:MOUNTING`` arguments, and the re-mounts the operator may do
MOUNTING_ARGS = ("pivoted", "remount")
REMOUNTS = get_args(Remount)


@dataclass
class _Axis:
    mode: str = "P"
    interlock_closed: bool = False
    rate_demand_dps: float = 0.0
    sine: tuple[float, float] = (0.0, 0.0)  # amplitude °, frequency Hz
    limits: dict[str, dict[str, float]] = field(default_factory=dict)  # mode → rate/accel


@dataclass
class _Log:
    rate_hz: float = LOG_RATE_HZ
    samples: int = 2000
    settle_s: float = 0.0
    label: str = ""
    mounting: Mounting = field(default_factory=Mounting)
    state: str = "IDLE"
    table: SampledLog | None = None
    log_id: int = 0
    #: the log is the head of a record the CAN logger streams (:meth:`daq_stream`)
    head: bool = False


class AcutrolController:
    """State machine of the simulated controller (thread-safe; one World)."""

    def __init__(self, world: World, lock: threading.RLock | None = None) -> None:
        self.world = world
        self.lock = lock or threading.RLock()
        self.axes = {1: _Axis(), 2: _Axis()}
        self.errors: list[CommandError] = []
        self.log = _Log()
        self.on_daq_log: Callable[[SampledLog], None] | None = None
        self._motion = False
        self._daq_started = False
        #: the DAQ streams this step's record (a timed record of the CAN logger)
        self._streamed = False
        self._pending = False
        self._target: dict[str, float] | None = None
        self._logs = 0
        self.world.motor_on = False

    # --- limits ----------------------------------------------------------------------------
    def factory(self, axis: int) -> tuple[float, float]:
        model = getattr(self.world.model.table, AXES[axis])
        return float(model.rate_limit_dps), float(model.accel_limit_dps2)

    def limit(self, axis: int, mode: str) -> tuple[float, float]:
        rate, accel = self.factory(axis)
        user = self.axes[axis].limits.get(mode, {})
        return min(rate, user.get("rate", rate)), min(accel, user.get("accel", accel))

    def set_limit(self, command: Command, kind: str) -> None:
        args = tuple(a.upper() if a.isalpha() else a for a in command.args)
        modes = [args[0]] if args and args[0] in ("P", "R", "S", "A") else ["P", "R", "S", "A"]
        start = 1 if len(modes) == 1 else 0
        if len(args) < start + 2:
            raise CommandError(-109, f"Missing parameter in {command.name}")
        axis = axis_of(Command(command.path, False, args[start:]))
        command = Command(command.path, False, args)
        value = numbers(command, 1, start + 1)[0]
        if kind in ("rate", "accel") and not 0 < value <= self.factory(axis)[kind == "accel"]:
            raise CommandError(-222, f"{kind} limit {value:g} beyond the factory limit")
        for mode in modes:
            self.axes[axis].limits.setdefault(mode, {})[kind] = value

    def _check(self, axis: int, mode: str, rate_dps: float, accel_dps2: float) -> None:
        rate_limit, accel_limit = self.limit(axis, mode)
        if rate_dps > rate_limit * (1 + 1e-6):
            raise CommandError(-222, f"Rate {rate_dps:g} exceeds the limit {rate_limit:g}")
        if accel_dps2 > accel_limit * (1 + 1e-6):
            raise CommandError(-222, f"Acceleration {accel_dps2:g} exceeds the limit "
                                     f"{accel_limit:g}")

    # --- modes and demands -----------------------------------------------------------------
    def _require_closed(self, axis: int) -> None:
        if not self.axes[axis].interlock_closed:
            raise CommandError(-221, f"Settings conflict; interlock of axis {axis} open")

    def set_mode(self, axis: int, mode: str) -> None:
        state = self.axes[axis]
        if state.mode != mode:
            self.stop_motion()
            state.mode = mode
            state.rate_demand_dps, state.sine = 0.0, (0.0, 0.0)

    def stop_motion(self) -> None:
        if self._motion:
            self.world.end_motion()
            self._motion = False
        self.log.state = "IDLE" if self.log.state != "DONE" else "DONE"
        self._daq_started = self._streamed = False

    def demand_position(self, axis: int, position_deg: float) -> None:
        self._require_closed(axis)
        if self.axes[axis].mode != "P":
            raise CommandError(-221, f"Settings conflict; axis {axis} not in position mode")
        low = self.axes[axis].limits.get("P", {}).get("low", -math.inf)
        high = self.axes[axis].limits.get("P", {}).get("high", math.inf)
        if not low <= position_deg <= high:
            raise CommandError(-222, f"Position {position_deg:g} outside [{low:g}, {high:g}]")
        self.stop_motion()
        if self._target is None:
            self._target = {"inner": self.world.inner_deg, "outer": self.world.outer_deg}
        self._target[AXES[axis]] = position_deg

    def demand_rate(self, axis: int, rate_dps: float) -> None:
        self._require_closed(axis)
        if self.axes[axis].mode not in ("R", "A"):
            raise CommandError(-221, f"Settings conflict; axis {axis} not in rate mode")
        self._check(axis, "R", abs(rate_dps), 0.0)
        self.axes[axis].rate_demand_dps = rate_dps
        self._pending = True

    def demand_oscillation(self, axis: int, amplitude_deg: float, frequency_hz: float) -> None:
        self._require_closed(axis)
        if self.axes[axis].mode != "S":
            raise CommandError(-221, f"Settings conflict; axis {axis} not in synthesis mode")
        if amplitude_deg < 0 or frequency_hz < 0:
            raise CommandError(-222, "Negative amplitude or frequency")
        omega = 2 * math.pi * frequency_hz
        self._check(axis, "S", amplitude_deg * omega, amplitude_deg * omega ** 2)
        self.axes[axis].sine = (amplitude_deg, frequency_hz)
        self._pending = True

    def _step(self) -> PlannedStep:
        """The step the modes and demands describe (like the Modbus simulator's)."""
        cfg = self.log
        common = {"id": cfg.label or f"log{self._logs + 1:05d}", "samples": cfg.samples,
                  "sample_rate_hz": cfg.rate_hz, "settle_s": cfg.settle_s,
                  "inner_deg": self.world.inner_deg, "outer_deg": self.world.outer_deg,
                  "mounting": cfg.mounting}
        for axis, name in AXES.items():
            amplitude, frequency = self.axes[axis].sine
            if self.axes[axis].mode == "S" and amplitude and frequency:
                return PlannedStep(kind="sine", axis=name, amplitude_deg=amplitude,
                                   frequency_hz=frequency, **common)
        inner, outer = (self.axes[a].rate_demand_dps if self.axes[a].mode in ("R", "A") else 0.0
                        for a in (1, 2))
        if inner or outer:
            return PlannedStep(kind="constant_rate", axis="inner", rate_dps=inner,
                               outer_rate_dps=outer, **common)
        return PlannedStep(kind="static", **common)

    def discard(self) -> None:
        """A line failed: none of its demands take effect."""
        self._pending, self._target = False, None

    def commit(self) -> None:
        """End of a command line: the demands it changed take effect together (one profile
        start for a two-axis demand, one move for two position demands, as the in-process
        table moves and begins a step once)."""
        if self._target is not None:
            target, self._target = self._target, None
            self.world.move_to(target["inner"], target["outer"])
        if self._pending:
            self._pending = False
            self._begin()

    def _begin(self) -> None:
        """(Re)start the World's profile from the current modes and demands; settle."""
        if self._motion:
            self.world.end_motion()
            self._motion = False
        step = self._step()
        if step.kind == "static" and self.log.state != "ARMING":
            return
        try:
            self.world.begin_motion(step)
        except EnvelopeRefused as exc:
            raise CommandError(-222, f"Data out of range: {exc}") from exc
        self._motion, self._daq_started, self._streamed = True, False, False
        self.log.state = "SETTLED"

    # --- interlocks ------------------------------------------------------------------------
    def interlock(self, axis: int, closed: bool) -> None:
        if not closed:
            self.stop_motion()
        self.axes[axis].interlock_closed = closed
        self.world.motor_on = all(a.interlock_closed for a in self.axes.values())

    # --- the log (simulator-side convention) -----------------------------------------------
    def configure_log(self, command: Command) -> None:
        rate_hz, samples, settle_s = numbers(command, 3, 0)
        capacity = self.world.model.table.log_capacity_samples
        if not 0 < rate_hz <= self.world.model.table.log_rate_hz * (1 + 1e-12):
            raise CommandError(-222, f"Log rate {rate_hz:g} Hz out of range")
        if not (samples == int(samples) and 0 < samples <= capacity) or settle_s < 0:
            raise CommandError(-222, f"Log of {samples:g} samples out of range (capacity "
                                     f"{capacity})")
        label = command.args[LABEL_ARG].strip('"') if len(command.args) > LABEL_ARG else ""
        self.log = _Log(rate_hz, int(samples), settle_s, label, log_id=self.log.log_id)

    def set_mounting(self, command: Command) -> None:
        """``:XLOG:MOUNTING pivoted,remount``: the simulated operator's mounting for this log."""
        if len(command.args) != len(MOUNTING_ARGS):
            raise CommandError(-109, f"{command.name} needs {','.join(MOUNTING_ARGS)}")
        pivoted, remount = command.args[0], command.args[1].lower()
        if pivoted not in ("0", "1") or remount not in REMOUNTS:
            raise CommandError(-224, f"Illegal parameter value in {command.name}: pivoted 0|1, "
                                     f"remount {'|'.join(REMOUNTS)}")
        self.log.mounting = Mounting(pivoted=pivoted == "1", remount=remount)

    def arm(self) -> None:
        if self.log.state not in ("SETTLED", "IDLE", "DONE"):
            raise CommandError(-221, f"Settings conflict; log {self.log.state.lower()}")
        if not self.world.motor_on and (self._motion or self._step().kind != "static"):
            # holding still needs no motor (a motor-off static step); motion does
            raise CommandError(-221, "Settings conflict; interlock open")
        if not self._motion:
            self.log.state = "ARMING"
            self._begin()
        self.log.state, self.log.table = "ARMED", None
        self._maybe_record()

    def daq_start(self) -> None:
        """The DAQ started logging: its trigger line goes high (called by the CAN logger)."""
        with self.lock:
            if self._daq_started or not self._motion:
                return
            self.world.start_daq()
            self._daq_started = True
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
            No step is in motion or a record already runs (the logger refuses the timed
            record).
        """
        with self.lock:
            if self._daq_started or not self._motion:
                raise ValueError("no step in motion, or a record already running")
            start_timed_record(self.world, samples)
            self._daq_started = self._streamed = True
        return stream_after_first_chunk(self.world, self._record_under_lock)

    def _record_under_lock(self) -> None:
        with self.lock:
            self._maybe_record()

    def _maybe_record(self) -> None:
        if self.log.state != "ARMED" or not self._daq_started:
            return
        self.log.state, self.log.head = "RECORDING", self._streamed
        threading.Thread(target=self._synthesise, args=(self.log,), daemon=True,
                         name="sim-acutrol-record").start()

    def _synthesise(self, record: _Log) -> None:
        """Run the twin for the armed log (worker thread: the server keeps answering); the
        head of a streamed record is the table's log alone (the DAQ log is being streamed)."""
        try:
            if record.head:
                table, daq = self.world.snapshot_log(self._head_step(record)), None
            else:
                result = self.world.result()
                table, daq = result.table, result.daq
        except Exception as exc:  # noqa: BLE001 - reported through the log state
            log.error("twin synthesis failed: %s: %s", type(exc).__name__, exc)
            with self.lock:
                record.state = "ERROR"
            return
        with self.lock:
            if self.log is not record:
                return
            if self.on_daq_log is not None and daq is not None:
                self.on_daq_log(daq)
            self._logs += 1
            record.table, record.log_id, record.state = table, self._logs, "DONE"

    def _head_step(self, record: _Log) -> PlannedStep:
        """The table log of a streamed record as configured: its rate and samples, at rest."""
        return PlannedStep(kind="static", id=record.label or f"log{self._logs + 1:05d}",
                           samples=record.samples, sample_rate_hz=record.rate_hz,
                           settle_s=record.settle_s, inner_deg=self.world.inner_deg,
                           outer_deg=self.world.outer_deg, mounting=record.mounting)

    def header(self) -> str:
        table = self.log.table
        if table is None:
            raise CommandError(-221, "Settings conflict; no completed log")
        return (f"{self.log.log_id},{len(table)},{table.sample_rate_hz:.17g},"
                f"{float(table.time_s[0]):.17g}")

    def data(self, command: Command) -> str:
        channel, start, count = (int(v) for v in numbers(command, 3, 0))
        table = self.log.table
        if table is None:
            raise CommandError(-221, "Settings conflict; no completed log")
        if not (0 <= channel < len(LOG_CHANNELS) and 0 <= start < len(table)
                and 0 < count <= DATA_MAX_COUNT):
            raise CommandError(-222, "Data out of range in :XLOG:DATA?")
        name = LOG_CHANNELS[channel]
        values = table.time_s if name == "time_s" else table[name]
        chunk = np.asarray(values[start:start + count], dtype=np.float64)
        return ",".join(np.char.mod("%.17g", chunk).tolist())
