"""Lazy synthesis of one recorded step: table log, DAQ log and the truth behind both.

Everything is computed on whole arrays from the World's record of the step: the real motion of
each axis (analytic in lab time), the DAQ clock and the sensor temperature. The table log is
sampled on the table clock from the trigger on; the DAQ log on its own crystal clock from
``start_lead_s`` before the trigger to ``stop_lag_s`` after the table log ends.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from aatest.engine.logs import DAQ, DAQ_AUX_CHANNELS, TABLE, TABLE_CHANNELS, SampledLog
from aatest.engine.steps import PlannedStep
from aatest.twin import kinematics as kin
from aatest.twin.chamber import ThermalState
from aatest.twin.clocks import TIMESTAMP_TICK_S, DaqClock, table_sync
from aatest.twin.daq import noiseless, record_channel
from aatest.twin.grid import Grid, sincos_deg
from aatest.twin.model import RigModel
from aatest.twin.sensor import SensorInputs, dynamics_filter, lowpass, output_volts
from aatest.twin.table import STENCIL_PAD, AxisTruth, estimate_quanta, estimates, floor_rocking


@dataclass(frozen=True)
class StepSetup:
    """Everything the World knows about one recorded step when the DAQ starts."""

    model: RigModel
    step: PlannedStep
    inner: AxisTruth
    outer: AxisTruth
    clock: DaqClock
    thermal: ThermalState
    #: channel → sensor axes (columns x, y, z) in table-top coordinates
    axes: dict[str, np.ndarray]
    stop_lag_s: float

    @property
    def gimbal(self) -> kin.GimbalErrors:
        return kin.GimbalErrors(self.model.table.orthogonality_arcsec,
                                self.model.table.wobble_arcsec)

    @property
    def trigger_index(self) -> int:
        return round(self.model.daq.start_lead_s * self.clock.sample_rate_hz)

    @property
    def trigger_time_s(self) -> float:
        """Lab time of the trigger = first table log sample."""
        return float(self.clock.lab_time(self.trigger_index / self.clock.sample_rate_hz))


class LazyTruth(Mapping[str, Any]):
    """The truth of a step; expensive entries (noise-free volts, undelayed sensor-axis
    acceleration) are computed on first access, so plugins that never look pay nothing.

    Deferred computations receive the mapping as their argument instead of closing over it:
    a closure cycle would keep whole records alive until a full garbage collection.
    """

    def __init__(self, **values: Any) -> None:
        self._values: dict[str, Any] = dict(values)
        self._deferred: dict[str, Callable[[LazyTruth], Any]] = {}

    def defer(self, key: str, compute: Callable[[LazyTruth], Any]) -> None:
        self._deferred[key] = compute

    def __setitem__(self, key: str, value: Any) -> None:
        self._values[key] = value

    def update(self, other: Mapping[str, Any]) -> None:
        self._values.update(other)

    def __getitem__(self, key: str) -> Any:
        if key not in self._values and key in self._deferred:
            self._values[key] = self._deferred.pop(key)(self)
        return self._values[key]

    def __iter__(self) -> Iterator[str]:
        yield from list(self._values) + [k for k in self._deferred if k not in self._values]

    def __len__(self) -> int:
        return len(set(self._values) | set(self._deferred))


@dataclass(frozen=True)
class SimulatedStep:
    """Both logs of one step and the truth behind them (see :func:`synthesise`)."""

    table: SampledLog
    daq: SampledLog
    truth: LazyTruth


def _table_log(setup: StepSetup, rng: np.random.Generator) -> tuple[SampledLog, dict[str, Any]]:
    step, tm = setup.step, setup.model.table
    dt = 1.0 / step.sample_rate_hz
    grid = Grid(setup.trigger_time_s - STENCIL_PAD * dt, dt, step.samples + 2 * STENCIL_PAD)
    channels: dict[str, np.ndarray] = {}
    truth: dict[str, Any] = {}
    axes = (("inner", setup.inner, tm.inner), ("outer", setup.outer, tm.outer))
    for name, axis, axis_model in axes:
        angle, rate, accel = axis.evaluate(grid)
        encoder = axis_model.encoder_error  # what the encoder reports, not where the table is
        seen = angle + encoder.error_deg(angle) if encoder is not None else angle
        est = estimates(seen, axis_model, dt, tm.estimator, rng)
        channels[f"{name}_position_deg"] = est["position_deg"]
        channels[f"{name}_rate_dps"] = est["rate_dps"]
        channels[f"{name}_accel_dps2"] = est["accel_dps2"]
        channels[f"{name}_feedback_deg"] = est["feedback_deg"]
        inner_slice = slice(STENCIL_PAD, STENCIL_PAD + step.samples)
        truth[f"{name}_angle_deg"] = angle[inner_slice]
        truth[f"{name}_rate_dps"] = rate[inner_slice]
        truth[f"{name}_accel_dps2"] = accel[inner_slice]
    time_s = np.arange(step.samples) * dt
    channels["sync_pulse"], channels["fp_latch_s"] = _table_pulse(setup, time_s, rng)
    moving = "outer" if step.axis == "outer" else "inner"
    truth.update(time_s=time_s, angle_deg=truth[f"{moving}_angle_deg"],
                 rate_dps=truth[f"{moving}_rate_dps"], accel_dps2=truth[f"{moving}_accel_dps2"])
    # encoder counts: the controller's log channels are integer multiples of these
    quanta = {f"{a}_{c}": (q, 0.0) for a, _, m in axes if m.encoder_resolution_deg > 0.0
              for c, q in estimate_quanta(m, dt, tm.estimator).items()}
    log = SampledLog(TABLE, step.sample_rate_hz, time_s,
                     _read_only({c: channels[c] for c in TABLE_CHANNELS}), dict(TABLE_CHANNELS),
                     {"time_s": (dt, 0.0), **quanta})
    return log, truth


def _read_only(channels: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Hand fresh arrays to the (immutable) log without the defensive copy it makes of
    writeable ones; nothing else holds them for writing."""
    for values in channels.values():
        values.flags.writeable = False
    return channels


def _table_pulse(setup: StepSetup, time_s: np.ndarray,
                 rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Sync pulse as registered by the table, with the latch times (table clock)."""
    clock, trig = setup.clock, setup.trigger_time_s
    daq_span = (np.array([time_s[0] - 0.05, time_s[-1] + 0.05]) + trig - clock.t0_s) / clock.scale
    edge_daq, rising = clock.edges(float(daq_span[0]), float(daq_span[1]), rng)
    edge_table = clock.lab_time(edge_daq) - trig
    level_before = 0.0 if rising[0] else 1.0
    return table_sync(edge_table, rising, level_before, time_s)


def _daq_samples(setup: StepSetup) -> int:
    """Number of DAQ samples: lead + the table record's span on the DAQ clock + stop lag."""
    step, clock = setup.step, setup.clock
    table_span_daq_s = step.samples / step.sample_rate_hz / clock.scale
    lag = setup.stop_lag_s
    return setup.trigger_index + int(np.ceil((table_span_daq_s + lag) * clock.sample_rate_hz))


def _top_motion(setup: StepSetup, grid: Grid,
                floor: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(α_top (3, n) °/s², up (3, n) g) of the table top on a lab-time grid, incl. parasitics
    and the floor's rocking ``floor`` (2, n) about the lab's horizontal axes."""
    th_i, w_i, a_i = setup.inner.evaluate(grid)
    th_o, w_o, a_o = setup.outer.evaluate(grid)
    sc_i = sincos_deg(th_i, setup.inner.profile.moving, setup.inner.profile.start_deg)
    sc_o = sincos_deg(th_o, setup.outer.profile.moving, setup.outer.profile.start_deg)
    alpha = kin.angular_acceleration_top(sc_i, w_i, a_i, w_o, a_o, setup.gimbal)
    table = setup.model.table
    if table.unbalance_parasitic_dps2_per_dps2 and setup.outer.profile.moving:
        # unbalanced payload: the outer axis' acceleration (incl. its ripple and motor band)
        # leaks into motion about the inner-base P axis through the controller's correction,
        # a resonance near 35 Hz: ≈k at low frequency, peaks in the motor band
        b, a = dynamics_filter(table.unbalance_resonance_hz, table.unbalance_damping,
                               round(grid.dt_s, 15))
        leak = table.unbalance_parasitic_dps2_per_dps2 * lowpass(a_o, b, a)
        alpha[0] += leak * sc_i[1]
        alpha[1] -= leak * sc_i[0]
    if floor is not None:
        alpha += kin.lab_horizontal_top(sc_i, sc_o, floor)
    return alpha, kin.gravity_top(sc_i, sc_o, setup.gimbal)


def _daq_log(setup: StepSetup, rng: np.random.Generator) -> tuple[SampledLog, LazyTruth]:
    model, clock = setup.model, setup.clock
    n = _daq_samples(setup)
    grid = Grid(clock.t0_s, clock.lab_dt_s, n)
    temperature = setup.thermal.temperature_at(grid.times)
    channels: dict[str, np.ndarray] = {}
    truth = LazyTruth(daq_time_s=grid.times - setup.trigger_time_s)
    motion: dict[float, tuple[np.ndarray, np.ndarray]] = {}
    floor = floor_rocking(model.table, n, clock.lab_dt_s, rng)
    for sensor in model.sensors:
        delay = sensor.time_delay.delay_s if sensor.time_delay is not None else 0.0
        if model.daq.logger_error is not None:  # the logger's own timing error (drawn)
            delay += model.daq.logger_error.timing_offset_s
        if delay not in motion:  # (the floor noise is not re-timed by the tiny delays)
            motion[delay] = _top_motion(setup, grid.shifted(-delay), floor)
        alpha, up = motion[delay]
        inp = SensorInputs(alpha, up, temperature, setup.axes[sensor.channel], clock.lab_dt_s)
        clean = output_volts(sensor, inp, model.t_ref_c)
        channels[sensor.channel] = record_channel(clean, sensor, model.daq, clock.lab_dt_s, rng)
        truth.defer(f"volts_{sensor.channel}",
                    lambda _, c=clean: noiseless(c, model.daq, clock.lab_dt_s))
    for sensor in model.sensors:  # true acceleration along each sensitive axis, undelayed
        axis_z = setup.axes[sensor.channel][:, 2]
        truth.defer(f"alpha_{sensor.channel}",
                    lambda _, z=axis_z: z @ _undelayed(setup, grid, motion, floor))
    channels_of = [s.channel for s in model.sensors]
    truth.defer("sensor_accel_dps2", lambda t: {ch: t[f"alpha_{ch}"] for ch in channels_of})
    channels["sync_pulse"] = clock.sync_level(clock.daq_times(n))
    channels["trigger"] = (np.arange(n) >= setup.trigger_index).astype(np.float64)
    channels["temperature_c"] = np.round(temperature, 2)
    units = {c: "V" for c in channels if c.startswith("v_")} | dict(DAQ_AUX_CHANNELS)
    lo_v, hi_v = model.daq.adc_range_v  # ADC codes: volts = code·LSB + low end (daq.quantise_adc)
    adc = {c: ((hi_v - lo_v) / 2**model.daq.adc_bits, lo_v) for c in channels if c.startswith("v_")}
    log = SampledLog(DAQ, clock.sample_rate_hz, clock.stamped(n, rng), _read_only(channels), units,
                     {"time_s": (TIMESTAMP_TICK_S, 0.0), **adc})
    return log, truth


def _undelayed(setup: StepSetup, grid: Grid, motion: dict[float, tuple[np.ndarray, np.ndarray]],
               floor: np.ndarray | None) -> np.ndarray:
    if 0.0 not in motion:
        motion[0.0] = _top_motion(setup, grid, floor)
    return motion[0.0][0]


def synthesise(setup: StepSetup, rng: np.random.Generator) -> SimulatedStep:
    """Table log, DAQ log and truth of one step (all vectorised)."""
    table, table_truth = _table_log(setup, rng)
    daq, truth = _daq_log(setup, rng)
    truth.update(table_truth)
    truth["drift_ppm"] = setup.clock.drift_ppm
    # t_table_log = offset + t_daq·(1 + drift): the DAQ's sample 0 precedes the trigger
    truth["offset_s"] = setup.clock.t0_s - setup.trigger_time_s
    truth["temperature_c"] = float(setup.thermal.temperature_at(setup.trigger_time_s))
    return SimulatedStep(table=table, daq=daq, truth=truth)
