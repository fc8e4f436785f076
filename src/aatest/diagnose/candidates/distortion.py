"""``jerk_distortion``: a second-order distortion of the rotor's response, c·(dα_r/dt)².

Its signature is a second harmonic (and a DC shift) whose size grows with the square of the
jerk, i.e. with f²·A² at acceleration amplitude A: negligible at 1 Hz, several per cent at
8 Hz and 400 °/s² (docs/method.md §1.3: the sensor's THD rises above ≈ 4 Hz and with
amplitude). Nothing falls at the fundamental, so no timing or dynamics effect competes with
it; the effects that also make harmonics do so at every frequency (the cubic at 3f from α³,
backlash and clipping at odd harmonics) or grow with frequency at the fundamental (jerk
sensitivity). One linear design column, in volts like ``jerk_sensitivity``: the squared jerk
of the sensed acceleration after the model's dynamics, as the twin applies it.
"""

from __future__ import annotations

import numpy as np

from aatest.diagnose.candidates.base import CandidateFit, Context, linear_ci
from aatest.diagnose.replay import sensor_acceleration

#: the largest jerk (°/s³) along the sensor axis must reach this: below it even a distortion
#: of 1e-7 (°/s²)/(°/s³)² (5 % at 8 Hz, 400 °/s²) is under 0.2 °/s² and no plan can see it
MIN_JERK_DPS3 = 2000.0


def peak_jerk_dps3(ctx: Context) -> float:
    """Largest |dα/dt| (°/s³) along the sensor axis over the dynamic steps."""
    peak = 0.0
    for s in ctx.replay.steps:
        if s.dynamic:
            a = sensor_acceleration(s, ctx.info.axis, s.time_s)[2]
            peak = max(peak, float(np.abs(np.gradient(a, s.dt_s)).max()))
    return peak


def testable_distortion(ctx: Context) -> str | None:
    if not ctx.dynamic_steps:
        return "no sine step: nothing excites the sensor dynamically"
    if peak_jerk_dps3(ctx) < MIN_JERK_DPS3:
        return f"no step reaches a jerk of {MIN_JERK_DPS3:g} °/s³ (fast, large sines needed)"
    return None


def fit_jerk_distortion(ctx: Context) -> CandidateFit:
    """The coefficient in V per (°/s³)², with its 95 % interval; the equivalent second
    harmonic at the plan's largest jerk, relative to the scale factor, as an extra."""
    fit = ctx.fit(ctx.current.spec.with_linear("jerk_distortion"))
    c, ci = linear_ci(ctx, fit, "jerk_distortion", divide_by_scale=False)
    peak = peak_jerk_dps3(ctx)
    return CandidateFit("jerk_distortion", fit, {"coefficient_v_per_dps3_squared": c},
                        {"coefficient_v_per_dps3_squared": ci},
                        extra={"second_harmonic_dps2_at_peak_jerk":
                               c * peak**2 / (2 * ctx.scale_of(fit))})
