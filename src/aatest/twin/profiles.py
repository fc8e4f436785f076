"""Commanded motion of one table axis as vectorised functions of lab time.

The controller's motion modes (docs/method.md §1.2, §3): position hold, constant rate and sine
synthesis; coordinated two-axis motion is two constant-rate profiles. A profile is evaluated at
any time array, so the table log (table clock) and the sensor (DAQ clock) see the same truth.
Limits are enforced here as the controller does — a command beyond them is refused, never run.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aatest.engine.errors import EnvelopeRefused
from aatest.engine.steps import PlannedStep
from aatest.twin.grid import Grid


@dataclass(frozen=True)
class AxisProfile:
    """θ(t) = start + rate·(t − t0) + A·sin(2πf·(t − t0)), degrees; t0 = motion start (s)."""

    start_deg: float = 0.0
    rate_dps: float = 0.0
    amplitude_deg: float = 0.0
    frequency_hz: float = 0.0
    t0_s: float = 0.0
    #: phase of the sine (the servo's steady-state lag/lead), radians
    phase_rad: float = 0.0

    @property
    def peak_rate_dps(self) -> float:
        return abs(self.rate_dps) + abs(self.amplitude_deg) * 2 * np.pi * self.frequency_hz

    @property
    def peak_accel_dps2(self) -> float:
        return abs(self.amplitude_deg) * (2 * np.pi * self.frequency_hz) ** 2

    @property
    def moving(self) -> bool:
        return self.rate_dps != 0.0 or (self.amplitude_deg != 0.0 and self.frequency_hz > 0.0)

    def evaluate(self, grid: Grid) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Commanded (angle_deg, rate_dps, accel_dps2) on a uniform lab-time grid."""
        # start + rate·(t − t0), in place (a·b and a + b commute bit for bit)
        angle = np.subtract(grid.times, self.t0_s)
        angle *= self.rate_dps
        angle += self.start_deg
        rate = np.full(grid.n, float(self.rate_dps))
        accel = np.zeros(grid.n)
        if self.amplitude_deg != 0.0 and self.frequency_hz > 0.0:
            w = 2 * np.pi * self.frequency_hz
            z = grid.phasor(w, self.phase_rad - w * self.t0_s)
            sin, cos = z.imag, z.real
            term = np.multiply(self.amplitude_deg, sin)  # one scratch array for the 3 terms
            angle += term
            rate += np.multiply(self.amplitude_deg * w, cos, out=term)
            accel -= np.multiply(self.amplitude_deg * w * w, sin, out=term)
        return angle, rate, accel

    def check(self, axis: str, rate_limit_dps: float, accel_limit_dps2: float) -> None:
        """Refuse the command when it exceeds the axis limits (controller-side guard)."""
        if self.peak_rate_dps > rate_limit_dps * (1 + 1e-9):
            raise EnvelopeRefused(
                f"{axis} axis: commanded rate {self.peak_rate_dps:.6g} °/s exceeds the "
                f"controller limit {rate_limit_dps:g} °/s; command refused")
        if self.peak_accel_dps2 > accel_limit_dps2 * (1 + 1e-9):
            raise EnvelopeRefused(
                f"{axis} axis: commanded acceleration {self.peak_accel_dps2:.6g} °/s² exceeds "
                f"the controller limit {accel_limit_dps2:g} °/s²; command refused")


def sine_amplitude_deg(step: PlannedStep) -> float:
    """Position amplitude of a sine step: given, or A = α/(2πf)² (docs/method.md §3)."""
    if step.amplitude_deg is not None:
        return float(step.amplitude_deg)
    if step.accel_dps2 is None or not step.frequency_hz:
        raise EnvelopeRefused(f"step {step.id}: sine needs amplitude_deg or accel_dps2 and "
                              "frequency_hz")
    return float(step.accel_dps2) / (2 * np.pi * step.frequency_hz) ** 2


def step_profiles(step: PlannedStep, t0_s: float) -> tuple[AxisProfile, AxisProfile]:
    """(inner, outer) commanded profiles of a step whose motion starts at lab time ``t0_s``.

    ``static``/``chamber``: hold at (inner_deg, outer_deg). ``sine``: sine synthesis on
    ``step.axis``. ``constant_rate``: ``rate_dps`` on the inner axis (or on ``axis`` when that is
    outer) and ``outer_rate_dps`` on the outer axis for coordinated two-axis motion.
    """
    inner = AxisProfile(start_deg=step.inner_deg, t0_s=t0_s)
    outer = AxisProfile(start_deg=step.outer_deg, t0_s=t0_s)
    if step.kind == "sine":
        sine = {"amplitude_deg": sine_amplitude_deg(step),
                "frequency_hz": float(step.frequency_hz or 0)}
        if step.axis == "outer":
            outer = AxisProfile(start_deg=step.outer_deg, t0_s=t0_s, **sine)
        else:
            inner = AxisProfile(start_deg=step.inner_deg, t0_s=t0_s, **sine)
    elif step.kind == "constant_rate":
        rate = float(step.rate_dps or 0.0)
        outer_rate = float(step.outer_rate_dps or 0.0)
        if step.axis == "outer" and step.outer_rate_dps is None:
            rate, outer_rate = 0.0, rate
        inner = AxisProfile(start_deg=step.inner_deg, rate_dps=rate, t0_s=t0_s)
        outer = AxisProfile(start_deg=step.outer_deg, rate_dps=outer_rate, t0_s=t0_s)
    return inner, outer
