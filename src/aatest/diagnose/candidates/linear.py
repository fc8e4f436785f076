"""Effects that add linear terms: temperature, cubic, gravity, cross-axis / misalignment.

Each one adds design columns whose coefficients, divided by the calibrated scale factor K,
are the contract parameters. They are testable only when the data vary the quantity the term
multiplies (temperature, |α| near range, the gravity component, non-sensitive-axis motion).
"""

from __future__ import annotations

import numpy as np

from aatest.diagnose.candidates.base import CandidateFit, Context, linear_ci
from aatest.diagnose.replay import gravity_along, sensor_acceleration

#: smallest temperature span that can reveal a temperature coefficient (°C)
MIN_TEMPERATURE_SPAN_C = 2.0
#: smallest span of the gravity component along the sensor axis (g)
MIN_GRAVITY_SPAN_G = 0.5
#: the cubic term needs accelerations of at least this fraction of the range
MIN_RANGE_FRACTION = 0.25
#: cross-axis needs this much peak acceleration about a non-sensitive axis (°/s²)
MIN_CROSS_DPS2 = 5.0


def _temperature_span(ctx: Context, dynamic_only: bool) -> float:
    temps = [float(np.mean(s.temperature_c)) for s in ctx.replay.steps
             if s.temperature_c is not None and (s.dynamic or not dynamic_only)]
    return max(temps) - min(temps) if len(temps) > 1 else 0.0


def testable_bias_temperature(ctx: Context) -> str | None:
    span = _temperature_span(ctx, False)
    return None if span >= MIN_TEMPERATURE_SPAN_C else (
        f"temperature spans {span:.1f} °C (< {MIN_TEMPERATURE_SPAN_C:g} °C)")


def testable_scale_temperature(ctx: Context) -> str | None:
    span = _temperature_span(ctx, True)
    return None if span >= MIN_TEMPERATURE_SPAN_C else (
        f"dynamic steps span {span:.1f} °C of temperature (< {MIN_TEMPERATURE_SPAN_C:g} °C)")


def testable_cubic(ctx: Context) -> str | None:
    from aatest.diagnose.candidates.base import dynamic_peak_dps2

    frac = dynamic_peak_dps2(ctx) / ctx.info.range_dps2
    return None if frac >= MIN_RANGE_FRACTION else (
        f"peak acceleration is {100 * frac:.0f} % of range (< {100 * MIN_RANGE_FRACTION:.0f} %)")


def testable_gravity(ctx: Context) -> str | None:
    g = [gravity_along(s, ctx.info.axis) for s in ctx.replay.steps]
    span = max(float(x.max()) for x in g) - min(float(x.min()) for x in g)
    return None if span >= MIN_GRAVITY_SPAN_G else (
        f"gravity along the sensor axis spans {span:.2f} g (< {MIN_GRAVITY_SPAN_G} g)")


def cross_excitation_dps2(ctx: Context) -> tuple[float, float]:
    """Peak |α_x|, |α_y| about the sensor's non-sensitive axes over all steps (°/s²)."""
    px = py = 0.0
    for s in ctx.replay.steps:
        if s.dynamic:
            a = sensor_acceleration(s, ctx.info.axis, s.time_s)
            px, py = max(px, float(np.abs(a[0]).max())), max(py, float(np.abs(a[1]).max()))
    return px, py


def testable_cross(ctx: Context) -> str | None:
    px, py = cross_excitation_dps2(ctx)
    return None if max(px, py) >= MIN_CROSS_DPS2 else (
        "no step excites a non-sensitive axis of the sensor (outer-axis motion needed)")


def fit_linear(ctx: Context, effect: str, params: tuple[str, ...] | None = None) -> CandidateFit:
    """One-column effects: the coefficient over K (or in volts for bias_temperature)."""
    fit = ctx.fit(ctx.current.spec.with_linear(effect))
    name = (params or _PARAM[effect])[0]
    value, ci = linear_ci(ctx, fit, effect, divide_by_scale=effect != "bias_temperature")
    return CandidateFit(effect, fit, {name: value}, {name: ci})


_PARAM = {
    "bias_temperature": ("coefficient_v_per_c",),
    "scale_temperature": ("coefficient_per_c",),
    "nonlinearity_cubic": ("c3",),
    "g_sensitivity": ("coefficient_dps2_per_g",),
}


def fit_cross(ctx: Context) -> CandidateFit:
    """Response to α about the sensor's x and y axes, relative to z (ratios)."""
    fit = ctx.fit(ctx.current.spec.with_linear("cross_axis"))
    px, py = cross_excitation_dps2(ctx)
    params, ci = {}, {}
    for col, key, peak in (("cross_x", "ratio_x", px), ("cross_y", "ratio_y", py)):
        if peak >= MIN_CROSS_DPS2:
            params[key], ci[key] = linear_ci(ctx, fit, col)
        else:
            params[key], ci[key] = 0.0, [0.0, 0.0]
    rx, ry = params["ratio_x"], params["ratio_y"]
    tilt = {"angle_deg": float(np.degrees(np.arctan(np.hypot(rx, ry)))),
            "azimuth_deg": float(np.degrees(np.arctan2(ry, rx)) % 360.0)}
    return CandidateFit("cross_axis", fit, params, ci, extra={"equivalent_misalignment": tilt})


def misalignment_from_cross(ctx: Context, cross: CandidateFit) -> CandidateFit:
    """The same fit read as a tilt of the input axis (angle from the reference axis)."""
    tilt = cross.extra["equivalent_misalignment"]
    rx, ry = cross.parameters["ratio_x"], cross.parameters["ratio_y"]
    r = float(np.hypot(rx, ry))
    ux = (cross.ci95["ratio_x"][1] - cross.ci95["ratio_x"][0]) / 2
    uy = (cross.ci95["ratio_y"][1] - cross.ci95["ratio_y"][0]) / 2
    u = float(np.hypot(ux * rx, uy * ry) / r) if r > 0 else float(np.hypot(ux, uy))
    lo, hi = np.degrees(np.arctan(max(r - u, 0.0))), np.degrees(np.arctan(r + u))
    return CandidateFit("misalignment", cross.fit, {"angle_deg": tilt["angle_deg"]},
                        {"angle_deg": [float(lo), float(hi)]},
                        extra={"azimuth_deg": tilt["azimuth_deg"]})
