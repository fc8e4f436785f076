"""The table top's rigid motion on a lab-time grid: every term of a DAQ block that draws
nothing at random (axis motion through the gimbal, gravity, the unbalance leak, the sensor
temperature), so it can be computed before, or on another thread while, the random streams
of that block are drawn (:func:`aatest.twin.synthesis.daq_blocks`).
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass
from functools import partial

import numpy as np

from aatest.twin import kinematics as kin
from aatest.twin.grid import Grid, sincos_deg
from aatest.twin.model import RigModel, SensorModel
from aatest.twin.sensor import dynamics_filter, lowpass
from aatest.twin.step_setup import StepSetup

#: the table top's motion on one grid before the floor's rocking is added: (α_top (3, n)
#: °/s², up (3, n) g, (sin, cos) of the inner angle, (sin, cos) of the outer angle)
TopMotion = tuple[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray],
                  tuple[np.ndarray, np.ndarray]]


def top_motion(setup: StepSetup, grid: Grid,
                floor: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(α_top (3, n) °/s², up (3, n) g) of the table top on a lab-time grid, incl. parasitics
    and the floor's rocking ``floor`` (2, n) about the lab's horizontal axes."""
    return with_floor(_rigid_motion(setup, grid), floor)


def with_floor(motion: TopMotion, floor: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """Add the floor's rocking to a :func:`_rigid_motion` (its α array, in place)."""
    alpha, up, sc_i, sc_o = motion
    if floor is not None:
        alpha += kin.lab_horizontal_top(sc_i, sc_o, floor)
    return alpha, up


#: the outer axis on one grid: ((angle °, rate °/s, acceleration °/s²), (sin, cos) of the angle)
OuterAxis = tuple[tuple[np.ndarray, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]


def _outer_axis(setup: StepSetup, grid: Grid) -> OuterAxis:
    """The outer axis' share of :func:`_rigid_motion` (thread-safe: reads ``setup`` only)."""
    evaluated = setup.outer.evaluate(grid)
    profile = setup.outer.profile
    return evaluated, sincos_deg(evaluated[0], profile.moving, profile.start_deg)


def _rigid_motion(setup: StepSetup, grid: Grid,
                  outer: Callable[[], OuterAxis] | None = None) -> TopMotion:
    """The table top's motion without the floor's rocking: every term that draws nothing at
    random, so it can be computed before (or while) the random streams are drawn. ``outer``
    gives the outer axis' share when another thread computes it (asked after the inner's)."""
    th_i, w_i, a_i = setup.inner.evaluate(grid)
    sc_i = sincos_deg(th_i, setup.inner.profile.moving, setup.inner.profile.start_deg)
    (_, w_o, a_o), sc_o = outer() if outer is not None else _outer_axis(setup, grid)
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
    return alpha, kin.gravity_top(sc_i, sc_o, setup.gimbal), sc_i, sc_o


def sensor_delay_s(model: RigModel, sensor: SensorModel) -> float:
    """How late a sensor channel sees the motion (its own delay and the logger's timing
    error, s): its motion is evaluated at t − delay."""
    delay = sensor.time_delay.delay_s if sensor.time_delay is not None else 0.0
    if model.daq.logger_error is not None:  # the logger's own timing error (drawn)
        delay += model.daq.logger_error.timing_offset_s
    return delay


@dataclass(frozen=True)
class RigidBlock:
    """What a DAQ generation block needs that draws nothing at random: the sensor
    temperature and, per sensor delay, the rigid motion of the table top."""

    temperature_c: np.ndarray
    motion: dict[float, TopMotion]


@dataclass(frozen=True)
class OuterPart:
    """The share of a block's :class:`RigidBlock` another thread can compute while this one
    computes the inner axis: per sensor delay the outer axis, and the sensor temperature."""

    outer: dict[float, OuterAxis]
    temperature_c: np.ndarray


def _delays(setup: StepSetup) -> list[float]:
    """The distinct sensor delays (s) of the rig, in sensor order."""
    return list(dict.fromkeys(sensor_delay_s(setup.model, s) for s in setup.model.sensors))


def outer_part(setup: StepSetup, grid: Grid) -> OuterPart:
    """:class:`OuterPart` of a block on the lab-time ``grid`` (thread-safe)."""
    return OuterPart({d: _outer_axis(setup, grid.shifted(-d)) for d in _delays(setup)},
                     setup.thermal.temperature_at(grid.times))


def rigid_block(setup: StepSetup, grid: Grid,
                 part: Future[OuterPart] | None = None) -> RigidBlock:
    """:class:`RigidBlock` of one generation block (thread-safe: reads ``setup`` only);
    ``part``: its :class:`OuterPart`, being computed on another thread."""
    if part is None:
        part = Future()
        part.set_result(outer_part(setup, grid))
    motion = {delay: _rigid_motion(setup, grid.shifted(-delay), partial(_outer_of, part, delay))
              for delay in _delays(setup)}  # (the floor noise is not re-timed by the tiny delays)
    return RigidBlock(part.result().temperature_c, motion)


def _outer_of(part: Future[OuterPart], delay: float) -> OuterAxis:
    return part.result().outer[delay]


def top_rate(setup: StepSetup, grid: Grid) -> np.ndarray:
    """Angular velocity (3, n) °/s of the table top on a lab-time grid (``rotor_stiction``
    gates on it; the floor's rocking, ≪ 0.01 °/s, is left out)."""
    th_i, w_i, _ = setup.inner.evaluate(grid)
    _, w_o, _ = setup.outer.evaluate(grid)
    sc_i = sincos_deg(th_i, setup.inner.profile.moving, setup.inner.profile.start_deg)
    return kin.angular_rate_top(sc_i, w_i, w_o, setup.gimbal)
