"""The World: one simulated rig's state in virtual lab time, shared by the sim plugins.

Holds the lab clock, the table's commanded state (angles, motor, current motion profile), the
chamber/sensor temperature and the mounting of the sensors (pivot, re-mount perturbations).
The simulated turntable, DAQ and chamber plugins drive it through the runner's call sequence
and share it through one :class:`~aatest.twin.session.TwinSession`; signals are synthesised
lazily, once per step, so the table log and the DAQ log see the same physical truth. Nothing
sleeps.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from aatest.engine.errors import EnvelopeRefused, RigFault
from aatest.engine.logs import SampledLog
from aatest.engine.steps import PlannedStep
from aatest.twin import kinematics as kin
from aatest.twin.chamber import ThermalState
from aatest.twin.clocks import DaqClock
from aatest.twin.grid import Grid
from aatest.twin.model import RigModel
from aatest.twin.profiles import AxisProfile, step_profiles
from aatest.twin.step_setup import SimulatedStep, StepSetup
from aatest.twin.step_synthesis import synthesise
from aatest.twin.synthesis import (
    SINGLE_BLOCK_MAX,
    concatenate_logs,
    daq_blocks,
    daq_record_samples,
)
from aatest.twin.table import AxisTruth, Tones, make_vibration, tracked
from aatest.twin.table_log import table_log


@dataclass(frozen=True)
class TableState:
    """The table at one lab time (s): both axes' positions (°) and rates (°/s)."""

    time_s: float
    inner_deg: float
    inner_dps: float
    outer_deg: float
    outer_dps: float


class World:
    """State of the simulated rig, advanced in virtual lab time by the plugins.

    Parameters
    ----------
    model
        The rig model (table, DAQ, chamber, sensors, unit).
    seed
        Seeds every random draw; the same seed and call sequence give identical logs.
    temperature_c
        Initial sensor/chamber temperature; default the chamber model's ambient.
    """

    def __init__(self, model: RigModel, seed: int = 0, temperature_c: float | None = None) -> None:
        self.model = model
        self.seed = int(seed)
        self._counter = 0
        self.lab_time_s = 0.0
        self.inner_deg = 0.0
        self.outer_deg = 0.0
        self.motor_on = False
        self.thermal = ThermalState.ambient(model.chamber, temperature_c)
        rng = self._rng("rig")
        self.vibration: dict[str, Tones | None] = {
            "inner": make_vibration(model.table.inner.motor_vibration, rng),
            "outer": make_vibration(model.table.outer.motor_vibration, rng),
        }
        self.drift_sign = {"inner": rng.choice([-1.0, 1.0]), "outer": rng.choice([-1.0, 1.0])}
        self.sync_phase = float(rng.uniform(0.05, 0.95))
        self.pivoted = False
        # with initial_mount_errors the first mounting is one draw of the re-mount spreads: a block
        # sits a little off on the table and each sensor a little off in its seat, which is
        # what makes (δ_e − δ_ep)/2 of the pivoted test differ from zero (docs/method.md §4.5)
        mount, unit = self._rng("mount"), model.unit
        drawn = unit.initial_mount_errors
        self.block_error = kin.random_small_rotation(
            mount, unit.block_remount_sigma_deg if drawn else 0.0)
        self.seat_error = {s.channel: kin.random_small_rotation(
            mount, unit.sensor_remount_sigma_deg if drawn else 0.0) for s in model.sensors}
        self._motion: tuple[PlannedStep, AxisTruth, AxisTruth] | None = None
        self._daq_start_s: float | None = None
        self._result: SimulatedStep | None = None

    # --- randomness ------------------------------------------------------------------------
    def _rng(self, label: str) -> np.random.Generator:
        """A generator seeded by (seed, label, counter): reproducible and independent per use."""
        digest = hashlib.sha256(f"{label}:{self._counter}".encode()).digest()
        return np.random.default_rng([self.seed, int.from_bytes(digest[:8], "little")])

    # --- mounting --------------------------------------------------------------------------
    def apply_mounting(self, step: PlannedStep) -> None:
        """Pivot and re-mount the sensors as the step's operator instruction says."""
        self.pivoted = step.mounting.pivoted
        remount, unit = step.mounting.remount, self.model.unit
        if remount == "none":
            return
        rng = self._rng(f"remount:{step.id}")
        if remount in ("block", "both"):
            self.block_error = kin.random_small_rotation(rng, unit.block_remount_sigma_deg)
        if remount in ("sensors", "both"):
            self.seat_error = {ch: kin.random_small_rotation(rng, unit.sensor_remount_sigma_deg)
                               for ch in self.seat_error}

    def sensor_axes(self) -> dict[str, np.ndarray]:
        """Channel → sensor (x, y, z) axes as columns in table-top coordinates.

        block error · seat frame · seat (re-mount) error · pivot · internal misalignment:
        the pivot turns the sensor, and so its internal misalignment, 180° about its seat z.
        """
        pivot = np.diag([-1.0, -1.0, 1.0]) if self.pivoted else np.eye(3)
        axes = {}
        for s in self.model.sensors:
            internal = (kin.tilt(s.misalignment.angle_deg, s.misalignment.azimuth_deg)
                        if s.misalignment is not None else np.eye(3))
            axes[s.channel] = (self.block_error @ kin.SEAT_FRAMES[s.axis]
                               @ self.seat_error[s.channel] @ pivot @ internal)
        return axes

    # --- table -----------------------------------------------------------------------------
    def _axis_truth(self, name: str, profile: AxisProfile, motor_on: bool) -> AxisTruth:
        axis_model = getattr(self.model.table, name)
        profile.check(name, axis_model.rate_limit_dps, axis_model.accel_limit_dps2)
        return AxisTruth(tracked(profile, axis_model.servo_bandwidth_hz), axis_model,
                         self.vibration[name], motor_on,
                         self.drift_sign[name] * axis_model.motor_off_drift_dps)

    def move_to(self, inner_deg: float, outer_deg: float) -> None:
        """Position both axes; advances lab time by a limit-rate move (trapezoidal estimate)."""
        t = 0.0
        deltas = (("inner", inner_deg - self.inner_deg), ("outer", outer_deg - self.outer_deg))
        for name, delta in deltas:
            ax = getattr(self.model.table, name)
            t = max(t, abs(delta) / ax.rate_limit_dps + ax.rate_limit_dps / ax.accel_limit_dps2
                    if delta else 0.0)
        self.inner_deg, self.outer_deg = float(inner_deg), float(outer_deg)
        self.lab_time_s += t + 0.5

    def begin_motion(self, step: PlannedStep) -> None:
        """Start the step's profile now (refused beyond limits) and settle ``step.settle_s``."""
        inner_p, outer_p = step_profiles(step.model_copy(update={
            "inner_deg": self.inner_deg, "outer_deg": self.outer_deg}), self.lab_time_s)
        motor = step.motor_on and self.motor_on
        if not motor and (inner_p.moving or outer_p.moving):
            raise EnvelopeRefused(f"step {step.id}: motion commanded with the motor off")
        truths = (self._axis_truth("inner", inner_p, motor),
                  self._axis_truth("outer", outer_p, motor))
        self.apply_mounting(step)
        self._motion = (step, *truths)
        self._result = None
        self.lab_time_s += step.settle_s

    def end_motion(self) -> None:
        """Stop the profile and return to the step's start position."""
        self._motion = None
        self.lab_time_s += 1.0

    def table_state(self) -> TableState:
        """Where the table is now: each axis's real position and rate at the lab time.

        During a step's motion, its truth (profile through the servo, ripple, vibration or
        drift) evaluated at ``lab_time_s``; at rest, the held position. Reads state only: the
        live status poll calls it from another thread while a step synthesises.
        """
        now_s, motion = self.lab_time_s, self._motion
        if motion is None:
            return TableState(now_s, self.inner_deg, 0.0, self.outer_deg, 0.0)
        at = Grid(now_s, 1.0, 1)
        (inner_deg, inner_dps, _), (outer_deg, outer_dps, _) = (
            truth.evaluate(at) for truth in motion[1:])
        return TableState(now_s, float(inner_deg[0]), float(inner_dps[0]),
                          float(outer_deg[0]), float(outer_dps[0]))

    # --- DAQ and synthesis -----------------------------------------------------------------
    def daq_clock(self, t0_s: float, sample_rate_hz: float | None = None) -> DaqClock:
        """The DAQ clock of a logging run started at lab time ``t0_s``.

        The logger is set to the step's rate (both loggers share the procedure's sampling,
        docs/interfaces.md §3); ``DaqModel.sample_rate_hz`` is the rate when none is given.
        """
        daq = self.model.daq
        drift = daq.clock_drift.drift_ppm if daq.clock_drift is not None else 0.0
        rate = daq.sample_rate_hz if sample_rate_hz is None else sample_rate_hz
        return DaqClock(t0_s, rate, drift, daq.timestamp_jitter_s,
                        daq.sync_pulse_hz, self.sync_phase, daq.sync_edge_jitter_s)

    def set_record_samples(self, samples: int) -> None:
        """Make the current step's record ``samples`` long after the trigger: a streaming
        logger's timed record sets its own length, which may exceed what the table logs (the
        simulated controllers learn the step from the table's log configuration)."""
        if self._motion is None:
            raise RigFault("simulated rig: record length set without begin_motion")
        step, inner, outer = self._motion
        self._motion = (step.model_copy(update={"samples": samples}), inner, outer)
        self._result = None

    def start_daq(self) -> None:
        """Start the DAQ (and its trigger) at the current lab time."""
        self._daq_start_s = self.lab_time_s
        self._result = None

    def _setup(self) -> StepSetup:
        """The current step's setup (the motion and the DAQ start are known)."""
        if self._motion is None or self._daq_start_s is None:
            raise RigFault("simulated rig: record requested without begin_motion and "
                           "start_logging")
        step, inner, outer = self._motion
        clock = self.daq_clock(self._daq_start_s, step.sample_rate_hz)
        return StepSetup(self.model, step, inner, outer, clock, self.thermal,
                         self.sensor_axes(), self.model.daq.stop_lag_s)

    def result(self) -> SimulatedStep:
        """Synthesise (once) the logs of the current step.

        A long record (more than :data:`SINGLE_BLOCK_MAX` DAQ samples) draws its DAQ log from
        a stream of its own, the one :meth:`stream_daq` uses, so both give the same log.
        """
        if self._result is not None:
            return self._result
        setup = self._setup()
        step = setup.step
        self._counter += 1
        long = daq_record_samples(setup) > SINGLE_BLOCK_MAX
        self._result = synthesise(setup, self._rng(f"step:{step.id}"),
                                  self._rng(f"daq:{step.id}") if long else None,
                                  self._rng(f"drift:{step.id}"))
        self.lab_time_s = float(setup.clock.t0_s + self._result.daq.time_s.size
                                * setup.clock.lab_dt_s)
        return self._result

    def stream_daq(self, blocks_per_chunk: int = 1) -> Iterator[SampledLog]:
        """The current step's DAQ log in chunks of ``blocks_per_chunk`` generation blocks.

        Generated lazily, one chunk in memory at a time, with the random streams and filter
        states a one-shot :meth:`result` of the same long record uses (same samples). Lab time
        advances as the chunks are taken.
        """
        setup = self._setup()
        step = setup.step
        self._counter += 1
        daq_rng, drift_rng = self._rng(f"daq:{step.id}"), self._rng(f"drift:{step.id}")
        start_s = float(setup.clock.t0_s)
        pending: list[SampledLog] = []
        for block in daq_blocks(setup, daq_rng, drift_rng=drift_rng):
            pending.append(block)
            if len(pending) >= blocks_per_chunk:
                yield concatenate_logs(pending)
                pending = []
            self.lab_time_s = max(self.lab_time_s, start_s + float(block.time_s[-1]))
        if pending:
            yield concatenate_logs(pending)
        self.lab_time_s = start_s + daq_record_samples(setup) * setup.clock.lab_dt_s

    def table_record(self, step: PlannedStep) -> SampledLog:
        """The table log the controller returns for ``step``: the step's own log, or, when
        the runner asks for a different length or rate (periodic snapshots while the DAQ
        streams a long record), the log at that rate."""
        motion = self._motion[0] if self._motion is not None else None
        if motion is not None and (step.samples, step.sample_rate_hz) != (
                motion.samples, motion.sample_rate_hz):
            return self.snapshot_log(step)
        return self.result().table

    def snapshot_log(self, table_step: PlannedStep) -> SampledLog:
        """The table log of the current step as ``table_step`` asks for it (the controller's
        periodic snapshots of a long record: its own rate and sample count)."""
        setup = self._setup()
        snapshot = StepSetup(self.model, table_step, setup.inner, setup.outer, setup.clock,
                             setup.thermal, setup.axes, setup.stop_lag_s)
        return table_log(snapshot, self._rng(f"table:{table_step.id}"))

    # --- chamber ---------------------------------------------------------------------------
    def set_temperature(self, setpoint_c: float) -> None:
        self.thermal.set_point(setpoint_c, self.lab_time_s)

    def wait_stable(self, soak_s: float) -> float:
        self.lab_time_s += self.thermal.time_to_stable_s(self.lab_time_s, soak_s)
        return float(self.thermal.temperature_at(self.lab_time_s))

    def wait_until_stable(self, tolerance_c: float, window_s: float,
                          max_s: float) -> tuple[float, float, float]:
        """Advance lab time until the sensor temperature is stable (see
        :meth:`ThermalState.time_to_spread_s`); return (°C, spread °C, soak s since the step).
        Not stable by ``max_s``: lab time advances to ``max_s`` and the soak is returned as is."""
        needed_s, spread_c = self.thermal.time_to_spread_s(tolerance_c, window_s)
        since_s = self.lab_time_s - self.thermal.step_time_s
        end_s = min(needed_s, max_s) if needed_s > since_s else since_s
        self.lab_time_s += max(0.0, end_s - since_s)
        if needed_s > max_s:  # the spread the window holds at max_s
            at = self.thermal.step_time_s + max_s
            spread_c = abs(float(self.thermal.temperature_at(at - window_s))
                           - float(self.thermal.temperature_at(at)))
        return float(self.thermal.temperature_at(self.lab_time_s)), spread_c, end_s

    def sensor_temperature_c(self) -> float:
        return float(self.thermal.temperature_at(self.lab_time_s))
