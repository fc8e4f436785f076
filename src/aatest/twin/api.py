"""Programmatic entry points to the twin for analyses, diagnose and tests.

``simulate_step`` runs one planned step through exactly the call sequence the runner uses on the
simulated plugins (move, begin motion, start DAQ, record, stop), so data built here is the data
a simulated run records. ``realistic_rig_model`` (from :mod:`aatest.twin.defaults`) gives the
measured-behaviour defaults of docs/method.md §1.2–1.3 and §2; ``nominal_rig_model`` the ideal
one clock / no error term model that ``diagnose`` replays (docs/interfaces.md §4).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from aatest.engine.steps import PlannedStep
from aatest.recording.dataset import Dataset, SensorInfo, StepData
from aatest.twin.defaults import realistic_rig_model
from aatest.twin.model import DaqModel, RigModel, SensorModel, TableModel, UnitModel
from aatest.twin.step_setup import SimulatedStep
from aatest.twin.world import World

__all__ = ["SimulatedStep", "World", "nominal_rig_model", "realistic_rig_model", "run_step",
           "sensor_infos", "simulate_dataset", "simulate_step"]


def run_step(world: World, step: PlannedStep) -> SimulatedStep:
    """Drive ``world`` through the runner's per-step sequence; return both logs and the truth."""
    if step.temperature_c is not None and step.temperature_c != world.thermal.setpoint_c:
        world.set_temperature(step.temperature_c)
        world.wait_stable(step.soak_s or 0.0)
    if not world.motor_on:
        world.motor_on = True
    world.move_to(step.inner_deg, step.outer_deg)
    world.begin_motion(step)
    world.start_daq()
    result = world.result()
    world.end_motion()
    return result


def simulate_step(model: RigModel, step: PlannedStep, seed: int, *,
                  temperature_c: float | None = None) -> SimulatedStep:
    """Simulate one recorded step on a fresh rig.

    Parameters
    ----------
    model
        Rig model (``RigModel()`` is minimal; see :func:`realistic_rig_model`).
    step
        A recorded step (``kind`` static, sine or constant_rate).
    seed
        Seed of every random draw.
    temperature_c
        Sensor temperature (°C), held constant; default the chamber ambient.

    Returns
    -------
    SimulatedStep
        ``table`` and ``daq`` logs plus ``truth``: ``time_s`` (table clock), ``accel_dps2``,
        ``rate_dps``, ``angle_deg`` of the moving axis and the same per axis
        (``inner_accel_dps2`` …), ``daq_time_s`` (DAQ samples on the table clock),
        ``alpha_<ch>`` / ``sensor_accel_dps2[ch]`` (acceleration along each sensor axis),
        ``volts_<ch>`` (noise-free output), ``drift_ppm``, ``offset_s``, ``temperature_c``.
    """
    world = World(model, seed, temperature_c)
    return run_step(world, step)


def sensor_infos(model: RigModel, serial: str = "sim") -> tuple[SensorInfo, ...]:
    """Datasheet-style nominals of the model's sensor channels."""
    return tuple(SensorInfo(channel=s.channel, axis=s.axis, nominal_bias_v=s.bias_v,
                            nominal_scale_v_per_dps2=s.scale_v_per_dps2,
                            range_dps2=s.range_dps2, model="sim", serial=serial)
                 for s in model.sensors)


def simulate_dataset(model: RigModel, steps: Sequence[PlannedStep], seed: int, *,
                     sensors: tuple[SensorInfo, ...] | None = None,
                     procedure: str = "sim") -> Dataset:
    """Simulate a whole plan on one rig (one World) and return it as a :class:`Dataset`.

    Chamber steps change the set-point and wait; every other step is recorded.
    """
    world = World(model, seed)
    world.motor_on = True
    data = []
    for step in steps:
        if not step.recorded:
            if step.temperature_c is not None:
                world.set_temperature(step.temperature_c)
            world.wait_stable(step.soak_s or 0.0)
            continue
        result = run_step(world, step)
        data.append(StepData(step=step, table=result.table, daq=result.daq))
    first = next((s.sample_rate_hz for s in steps if s.recorded), model.table.log_rate_hz)
    return Dataset(procedure=procedure, sample_rate_hz=first,
                   sensors=sensors if sensors is not None else sensor_infos(model),
                   steps=tuple(data), source=Path(f"<sim seed={seed}>"),
                   metadata={"simulated": True, "seed": seed,
                             "model": model.model_dump(mode="json")})


def nominal_rig_model(sensors: Sequence[SensorModel] | None = None) -> RigModel:
    """One clock, ideal dynamics, no error terms: the replay model of ``diagnose``.

    Sensors keep only bias, scale factor, range and axis (noise 0); the table has no ripple,
    vibration, drift or estimator noise; the DAQ has no drift, jitter or pre-sample filter and
    a 32-bit ADC; the unit is mounted perfectly (no mounting or re-mount errors).
    """
    keep = ("channel", "axis", "bias_v", "scale_v_per_dps2", "range_dps2")
    plain = [SensorModel(**{k: getattr(s, k) for k in keep}, noise_rms_v=0.0)
             for s in (sensors or [SensorModel()])]
    axis = {"encoder_noise_deg": 0.0, "encoder_resolution_deg": 0.0, "estimate_noise_deg": 0.0,
            "motor_off_drift_dps": 0.0, "servo_bandwidth_hz": 0.0}
    base = TableModel()
    table = base.model_copy(update={
        "inner": base.inner.model_copy(update=axis), "outer": base.outer.model_copy(update=axis),
        "wobble_arcsec": 0.0, "orthogonality_arcsec": 0.0})
    daq = DaqModel(timestamp_jitter_s=0.0, antialias_hz=None, adc_bits=32)
    unit = UnitModel(sensor_remount_sigma_deg=0.0, block_remount_sigma_deg=0.0)
    return RigModel(sensors=plain, table=table, daq=daq, unit=unit)
