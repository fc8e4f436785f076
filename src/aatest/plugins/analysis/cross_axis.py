"""Cross-axis sensitivity of a single-axis sensor from outer-axis excitation (issue 32).

A sensor on the inner axis (I) sees the outer axis' angular acceleration only through its
cross-axis sensitivity (and any tilt of its input axis). With the inner axis held at θ, the
outer axis lies at angle θ in the sensor's transverse plane, so the output's in-phase response
to the outer-axis acceleration, over the scale factor K, is

    r(θ) = c_x·cos θ + c_y·sin θ.

Each outer-axis sine step gives r(θ) from the fundamentals (at the step's whole-cycle
frequency) of the output and of the logged outer-axis acceleration: r = Re(V̂/Â)/K. Two or more
positions at least 45° apart give (c_x, c_y) by least squares, and the judged cross-axis ratio
is |c| = √(c_x² + c_y²), the worst transverse direction's. U (k = 2) propagates each r's Type A
standard uncertainty (the residual of the fundamental fit) through the solve; K is the run's
calibrated scale factor, else the datasheet's (its relative uncertainty scales |c| and is
negligible against the ≈10⁻³ Type A term at a ratio of a few 10⁻³).
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from aatest.clocksync.freeze_pulse import SyncedStep
from aatest.engine.errors import AnalysisError
from aatest.engine.interfaces import AnalysisContext, AnalysisOutput, NoOptions
from aatest.engine.requirements import Requirement
from aatest.plugins.analysis import needs
from aatest.plugins.analysis._common import scale_in_use, steps_of
from aatest.recording.dataset import Dataset, SensorInfo
from aatest.results.cross_axis import CrossAxisResult

#: coverage factor of the stated U (≈95 % for a normal distribution)
COVERAGE_K = 2.0
#: inner-axis positions the transverse plane needs (two directions)
MIN_POSITIONS = 2


def fundamental(x: np.ndarray, t_s: np.ndarray, frequency_hz: float) -> tuple[complex, float]:
    """Complex amplitude c (x ≈ Re(c·e^{jωt}) + mean) and its standard uncertainty |u(c)|,
    from the least-squares residual (both quadratures)."""
    phase = 2.0 * math.pi * frequency_hz * (t_s - t_s[0])
    design = np.column_stack([np.cos(phase), -np.sin(phase), np.ones_like(phase)])
    coef, *_ = np.linalg.lstsq(design, x, rcond=None)
    dof = max(x.size - design.shape[1], 1)
    sigma = float(np.sqrt(np.sum((x - design @ coef) ** 2) / dof))
    cov = sigma**2 * np.linalg.inv(design.T @ design)
    return complex(coef[0], coef[1]), float(np.sqrt(cov[0, 0] + cov[1, 1]) / math.sqrt(2.0))


def step_ratio(step: SyncedStep, channel: str, scale_v_per_dps2: float) -> tuple[float, float]:
    """r(θ) of one outer-axis sine step and its standard uncertainty (Type A)."""
    f_hz = step.step.frequency_hz
    if f_hz is None:
        raise AnalysisError(f"step {step.step.id}: a sine step without a frequency")
    volts = np.asarray(step.daq[channel], dtype=np.float64)
    accel = np.asarray(step.table["outer_accel_dps2"], dtype=np.float64)
    v_hat, u_v = fundamental(volts, step.time_s, f_hz)
    a_hat, _u_a = fundamental(accel, step.time_s, f_hz)
    if abs(a_hat) == 0.0:
        raise AnalysisError(f"step {step.step.id}: no outer-axis acceleration at {f_hz:g} Hz")
    ratio = (v_hat / a_hat).real / scale_v_per_dps2
    return float(ratio), u_v / abs(a_hat) / abs(scale_v_per_dps2)


def solve(theta_deg: np.ndarray, ratios: np.ndarray, u: np.ndarray) -> dict[str, Any]:
    """(c_x, c_y) by weighted least squares, |c| and U(|c|) (k = 2) by linear propagation."""
    th = np.deg2rad(theta_deg)
    design = np.column_stack([np.cos(th), np.sin(th)])
    weights = 1.0 / np.maximum(u, np.finfo(float).tiny) ** 2
    normal = design.T @ (weights[:, None] * design)
    cov = np.linalg.inv(normal)
    c = cov @ design.T @ (weights * ratios)
    size = float(np.hypot(*c))
    grad = c / size if size > 0 else np.array([1.0, 0.0]) / math.sqrt(2.0)
    u_size = float(np.sqrt(grad @ cov @ grad))
    return {"cross_axis_ratio": size, "ratio_x": float(c[0]), "ratio_y": float(c[1]),
            "expanded_uncertainty": COVERAGE_K * u_size, "coverage_factor": COVERAGE_K}


class CrossAxisAnalysis:
    """Cross-axis ratio of each sensor on the inner axis, from outer-axis sine steps at two or
    more inner-axis positions (each with U and judged against ``cross_axis_ratio``)."""

    key: ClassVar[str] = "cross_axis"
    requires: ClassVar[tuple[str, ...]] = ("sync", "scale_factor")
    #: what the plan must hold (checked by ``validate``; aatest.engine.requirements)
    requirements: ClassVar[tuple[Requirement, ...]] = needs.CROSS_AXIS
    #: the acceptance quantities it produces (judged when it is listed)
    judges: ClassVar[tuple[str, ...]] = ("cross_axis_ratio",)
    Options: ClassVar[type[NoOptions]] = NoOptions
    Result: ClassVar[type[CrossAxisResult]] = CrossAxisResult

    def applies_to(self, data: Dataset) -> bool:
        return any(s.axis == "I" for s in data.sensors) and len(needs.cross_axis_positions(
            [p for p in data.planned if p.kind == "sine" and p.axis == "outer"])) >= MIN_POSITIONS

    def run(self, data: Dataset, context: AnalysisContext) -> AnalysisOutput[CrossAxisResult]:
        steps = steps_of(context, "sine").where(lambda p: p.axis == "outer")
        values = {sensor.channel: self._channel(list(steps), sensor, context)
                  for sensor in data.sensors if sensor.axis == "I"}
        return AnalysisOutput(CrossAxisResult.model_validate(values), {})

    @staticmethod
    def _channel(steps: list[SyncedStep], sensor: SensorInfo,
                 context: AnalysisContext) -> dict[str, Any]:
        scale = scale_in_use(context, sensor)
        measured = [step_ratio(s, sensor.channel, scale) for s in steps]
        theta = np.array([s.step.inner_deg for s in steps], dtype=np.float64)
        ratios = np.array([r for r, _u in measured])
        u = np.array([u for _r, u in measured])
        return {**solve(theta, ratios, u), "positions_deg": theta.tolist(),
                "ratios": ratios.tolist(), "standard_uncertainties": u.tolist(),
                "steps": [s.step.id for s in steps], "scale_v_per_dps2_used": scale}
