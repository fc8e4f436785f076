"""Measurement models and uncertainty budgets (GUM, k = 2) for the calibration certificate.

Each ``*_measurand`` function turns an analysis result plus rig constants into a
:class:`~aatest.engine.uncertainty.gum.Measurand`: the final quantity's model with one input per
budget row (fit/reference noise, sensor noise, table position accuracy, wobble/orthogonality,
sync residual, environment temperature, repeatability over repetitions). Statistical inputs
come from the analysis (ci95, per-repetition values, measured noise); the rest are the rig's
stated accuracies (:class:`RigConstants`, docs/method.md §1.2). Quantities are propagated with
``uncertainties`` (first order) and checked against Monte Carlo in the tests.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from aatest.engine.datasheet import REFERENCE_SCALE_V_PER_DPS2
from aatest.engine.uncertainty import access as ex
from aatest.engine.uncertainty.gum import Input, Measurand, Ops

ARCSEC_RAD = math.pi / (180.0 * 3600.0)


class RigConstants(BaseModel):
    """Stated accuracies of the rig that enter every budget (docs/method.md §1.2, §2)."""

    model_config = ConfigDict(frozen=True, extra="forbid")
    position_accuracy_arcsec: float = Field(1.0, ge=0, description="table positioning, 1″ RSS")
    wobble_arcsec: float = Field(2.0, ge=0, description="inner-axis wobble bound")
    orthogonality_arcsec: float = Field(3.0, ge=0, description="inner/outer orthogonality bound")
    temperature_stability_c: float = Field(0.2, ge=0, description="± band during a record")
    thermometer_uncertainty_c: float = Field(0.1, ge=0, description="standard, per reading")
    noise_bandwidth_hz: float = Field(100.0, gt=0, description="anti-alias filter corner")
    record_samples: int = Field(131_072, gt=0, description="samples per record if not stated")
    sample_rate_hz: float = Field(2000.0, gt=0)
    static_record_s: float = Field(67.5, gt=0, description="static record if not stated")
    temperature_span_c: float = Field(69.0, gt=0, description="−21…48 °C if not stated")


def _rel(name: str, label: str, u: float, note: str, dist: str = "normal") -> Input:
    return Input(name, label, 0.0, u, dist, "1", note)  # type: ignore[arg-type]


def _scale_fit_inputs(entry: Mapping[str, Any], k_v: float, noise_v: float,
                      results: Mapping[str, Any], c: RigConstants, where: str) -> list[Input]:
    """Split the fit's relative uncertainty into reference-noise and sensor-noise parts.

    The slope variance of a least-squares fit is proportional to the residual variance,
    which is the sum of reference-acceleration noise and sensor noise (in °/s²); each part
    of the budget gets its share of it.
    """
    coeffs = ex.require(entry, "coefficients", where) or []
    a1 = ex.as_float(coeffs[1]) if len(coeffs) > 1 else None
    u_a1 = ex.ci_std(ex.require(entry, "ci95", where), 1) if a1 else None
    u_k = ex.as_float(entry.get("scale_u_v_per_dps2")) or ex.ci_std(entry.get("scale_ci95"))
    rmse = ex.require_float(entry, "rmse_dps2", where)
    sine = ex.steps_of_kind(results, "sine")
    if u_k is not None:
        rel_fit, source = u_k / k_v, "from the analysis' u(K)"
    elif u_a1 is not None and a1:
        rel_fit, source = u_a1 / abs(a1), "from the fit's ci95 of a1"
    elif rmse is not None:
        peak = max(ex.step_values(sine, "accel_dps2") or [400.0])
        n = sum(ex.step_values(sine, "samples")) or c.record_samples
        rel_fit, source = rmse / (peak * math.sqrt(n / 2.0)), "from RMSE and record length"
    else:
        return []
    share = min(1.0, (noise_v / k_v) / rmse) if rmse else 0.0
    return [
        _rel("fit_reference", "reference acceleration (fit residual)",
             rel_fit * math.sqrt(1.0 - share**2), f"reference noise part of the fit, {source}"),
        _rel("fit_noise", "sensor noise (fit residual)", rel_fit * share,
             f"sensor-noise part of the fit, {noise_v * 1e3:.2f} mV RMS"),
    ]


def _reference_amplitude_deg(results: Mapping[str, Any]) -> float:
    """Typical sine position amplitude A = α/(2πf)² of the calibration records (deg)."""
    amps = ex.step_values(ex.steps_of_kind(results, "sine"), "amplitude_deg")
    if amps:
        return float(sorted(amps)[len(amps) // 2])
    return 400.0 / (2 * math.pi) ** 2


def _sync_rate_rel(results: Mapping[str, Any]) -> float:
    """Relative clock-rate uncertainty left after the sync fit: σ_res·√(12/n) / T."""
    sync = ex.analysis(results, "sync") or {}
    residual_s = (ex.as_float(sync.get("residual_rms_us")) or 3.5) * 1e-6
    edges = ex.as_float(sync.get("edges_used")) or 6553.0
    span_s = max(edges, 2.0) / 100.0  # 100 Hz sync pulse
    return residual_s * math.sqrt(12.0 / max(edges, 2.0)) / span_s


def _repeat_input(entry: Mapping[str, Any], key: str, scale: float, unit: str) -> list[Input]:
    values = ex.repetition_values(entry, key)
    u = ex.std_of_mean(values)
    if u is None:
        return []
    return [Input("repeatability", "repeatability over repetitions", 0.0, u / scale, "normal",
                  unit, f"s/√n over {len(values)} repetitions")]


def _inputs(inputs: Sequence[Input]) -> tuple[Input, ...]:
    return tuple(inputs)


def scale_factor_measurand(results: Mapping[str, Any], channel: str,
                           c: RigConstants) -> Measurand | None:
    """K = K̂·(1 + e_fit + e_rep) / ((1 + e_pos)·(1 + e_clk)²·(1 + e_wob))  [V/(°/s²)].

    α = (2πf)²·A, so the reference scales with the amplitude A (position accuracy) and with
    f² (clock rate after sync); an axis tilt ε scales it by cos ε.
    """
    entry = ex.channel_entry(results, "scale_factor", channel)
    where = f"analysis.scale_factor.{channel}"
    k_hat = ex.require_float(entry, "scale_v_per_dps2", where) if entry is not None else None
    if k_hat is None:
        return None
    noise_v, _ = ex.noise_rms_v(results, channel)
    amp_arcsec = _reference_amplitude_deg(results) * 3600.0
    inputs = [
        *_scale_fit_inputs(entry, k_hat, noise_v, results, c, where),
        _rel("position", "table position accuracy", c.position_accuracy_arcsec / amp_arcsec,
             f"{c.position_accuracy_arcsec:g}″ over a {amp_arcsec / 3600:.3g}° amplitude",
             "rectangular"),
        _rel("clock", "sync residual (clock rate)", _sync_rate_rel(results),
             "rate of the fitted clock relation"),
        Input("wobble", "wobble / orthogonality (axis tilt)", 0.0,
              math.hypot(c.wobble_arcsec, c.orthogonality_arcsec) * ARCSEC_RAD, "cosine_error",
              "1", "cos ε − 1, ε uniform within the combined bound"),
        *_repeat_input(entry, "scale_v_per_dps2", k_hat, "1"),
    ]

    def model(ops: Ops, x: Mapping[str, Any]) -> Any:
        fit = 1.0 + sum(x.get(k, 0.0) for k in ("fit_reference", "fit_noise", "repeatability"))
        return k_hat * fit / ((1.0 + x["position"]) * (1.0 + x["clock"]) ** 2 * (1.0 + x["wobble"]))

    return Measurand(f"scale factor {channel}", "V/(°/s²)", model, _inputs(inputs))


def _static_mean_std_v(results: Mapping[str, Any], channel: str, c: RigConstants,
                       records: int) -> tuple[float, str]:
    """Standard uncertainty of one static mean: σ / √(2·B·T) per record, over ``records``."""
    noise_v, source = ex.noise_rms_v(results, channel)
    static = ex.steps_of_kind(results, "static")
    duration_s = min(ex.step_values(static, "duration_s") or [c.static_record_s])
    independent = 2.0 * c.noise_bandwidth_hz * duration_s * max(records, 1)
    note = f"{noise_v * 1e3:.2f} mV RMS ({source}), {records}×{duration_s:g} s, B = " \
           f"{c.noise_bandwidth_hz:g} Hz"
    return noise_v / math.sqrt(independent), note


def _mounting_u(entry: Mapping[str, Any], u_key: str) -> float | None:
    """u of the mean over mountings (original/pivoted) when only those are reported."""
    mountings = entry.get("mountings")
    if not isinstance(mountings, Mapping):
        return None
    us = [ex.as_float(m.get(u_key)) for m in mountings.values() if isinstance(m, Mapping)]
    if not us or any(u is None for u in us):
        return None
    return math.sqrt(sum(u * u for u in us if u is not None)) / len(us)


def _static_statistics(results: Mapping[str, Any], entry: Mapping[str, Any], channel: str,
                       c: RigConstants, key: str, u_key: str, volts_per_unit: float,
                       unit: str) -> list[Input]:
    """Type A inputs of a static quantity: the analysis' own u when stated (it already holds
    noise and repeatability), else sensor noise over the records plus repeatability."""
    u = ex.as_float(entry.get(u_key)) or _mounting_u(entry, u_key)
    if u is not None:
        return [Input("noise", "static means (noise, repeatability)", 0.0, u, "normal", unit,
                      "type A, from the analysis")]
    reps = max(len(ex.repetition_values(entry, key)), 1)
    u_mean, note = _static_mean_std_v(results, channel, c, 2 * reps)
    return [Input("noise", "sensor noise", 0.0, u_mean / volts_per_unit, "normal", unit, note),
            *_repeat_input(entry, key, 1.0, unit)]


def _bias_tc_v_per_c(results: Mapping[str, Any], channel: str) -> float:
    temp = (ex.analysis(results, "temperature") or {}).get(channel) or {}
    measured = ex.as_float(temp.get("bias_coefficient_v_per_c"))
    if measured is not None:
        return abs(measured)
    limit = ex.as_float(ex.sensors(results).get(channel, {}).get("bias_temperature_limit_v_per_c"))
    return limit or 0.0004


def bias_measurand(results: Mapping[str, Any], channel: str, c: RigConstants) -> Measurand | None:
    """b = b̂ + e_noise + e_temp + e_rep  [V]; b̂ = (A+ + A−)/2 cancels table tilt exactly."""
    entry = ex.channel_entry(results, "bias", channel)
    where = f"analysis.bias.{channel}"
    b_hat = ex.require_float(entry, "bias_v", where) if entry is not None else None
    if b_hat is None:
        return None
    tc = _bias_tc_v_per_c(results, channel)
    inputs = [
        *_static_statistics(results, entry, channel, c, "bias_v", "bias_u_v", 1.0, "V"),
        Input("temperature", "environment temperature", 0.0, tc * c.temperature_stability_c,
              "rectangular", "V", f"±{c.temperature_stability_c:g} °C × {tc * 1e3:.2f} mV/°C"),
    ]

    def model(ops: Ops, x: Mapping[str, Any]) -> Any:
        return b_hat + x["noise"] + x["temperature"] + x.get("repeatability", 0.0)

    return Measurand(f"bias {channel}", "V", model, _inputs(inputs))


def _scale_input(results: Mapping[str, Any], channel: str, scale_rel_u: float | None) -> Input:
    """K's relative uncertainty: calibrated in this run, else its datasheet tolerance."""
    if scale_rel_u is not None:
        return _rel("scale", "scale factor", scale_rel_u, "relative u_c(K)/K of this calibration")
    tol_pct = ex.as_float(ex.sensors(results).get(channel, {}).get("scale_tolerance_pct")) or 1.0
    return _rel("scale", "scale factor", tol_pct / 100.0,
                f"nominal K, datasheet ±{tol_pct:g} % (not calibrated in this run)", "rectangular")


def g_sensitivity_measurand(results: Mapping[str, Any], channel: str, c: RigConstants,
                            scale_rel_u: float | None) -> Measurand | None:
    """G = (Ĝ + e_noise + e_temp + e_rep) / ((1 + e_K)·(1 + e_tilt))  [(°/s²)/g].

    Ĝ = (A+ − A−)/(2K): the half-difference carries the noise of both means and any bias
    drift between them; dividing by K carries the scale factor's relative uncertainty (its
    datasheet tolerance when the run did not calibrate K, ``scale_rel_u=None``); a
    tilt ε of the table reduces the ±1 g projection by cos ε.
    """
    entry = ex.channel_entry(results, "bias", channel)
    where = f"analysis.bias.{channel}"
    g_hat = (ex.require_float(entry, "g_sensitivity_dps2_per_g", where)
             if entry is not None else None)
    if g_hat is None:
        return None
    nominal = ex.sensors(results).get(channel, {}).get("nominal_scale_v_per_dps2")
    k_v = (ex.as_float(entry.get("scale_v_per_dps2_used")) or ex.as_float(nominal)
           or REFERENCE_SCALE_V_PER_DPS2)
    tc = _bias_tc_v_per_c(results, channel)
    tilt = math.hypot(c.position_accuracy_arcsec, c.wobble_arcsec) * ARCSEC_RAD
    inputs = [
        *_static_statistics(results, entry, channel, c, "g_sensitivity_dps2_per_g",
                            "g_sensitivity_u_dps2_per_g", k_v, "(°/s²)/g"),
        Input("temperature", "environment temperature", 0.0,
              tc * c.temperature_stability_c / (2 * k_v), "rectangular", "(°/s²)/g",
              "bias drift between the +1 g and −1 g records"),
        _scale_input(results, channel, scale_rel_u),
        Input("tilt", "table position / wobble (tilt)", 0.0, tilt, "cosine_error", "1",
              "cos ε − 1 of the gravity projection"),
    ]

    def model(ops: Ops, x: Mapping[str, Any]) -> Any:
        g = g_hat + x["noise"] + x["temperature"] + x.get("repeatability", 0.0)
        return g / ((1.0 + x["scale"]) * (1.0 + x["tilt"]))

    return Measurand(f"g-sensitivity {channel}", "(°/s²)/g", model, _inputs(inputs))


#: temperature-analysis key → (per-point value key, unit) for the two coefficients
TEMPERATURE_COEFFICIENTS: dict[str, tuple[str, str]] = {
    "bias_coefficient_v_per_c": ("bias_v", "V/°C"),
    "scale_coefficient_per_c": ("scale_v_per_dps2", "1/°C"),
}


def _slope_std(entry: Mapping[str, Any], key: str, point_key: str) -> tuple[float | None, str]:
    """Standard uncertainty of a temperature slope: ci95, else a regression over the points."""
    from scipy.stats import linregress

    stated = ex.as_float(entry.get(key.replace("_coefficient_", "_coefficient_u_")))
    if stated is not None:
        return stated, "from the analysis' u"
    u = ex.ci_std(entry.get(key.replace("_coefficient_", "_coefficient_ci95_")))
    if u is None and isinstance(entry.get("ci95"), Mapping):
        u = ex.ci_std(entry["ci95"], key)
    if u is not None:
        return u, "from the analysis' ci95"
    points = ex.temperature_points(entry, point_key)
    if len(points) >= 3:
        t = [float(p["temperature_c"]) for p in points]
        y = [float(p[point_key]) for p in points]
        if point_key == "scale_v_per_dps2":  # relative coefficient: normalise by the mean
            mean = sum(y) / len(y)
            y = [v / mean for v in y]
        return float(linregress(t, y).stderr), f"regression over {len(points)} temperature points"
    return None, ""


def _temperature_span_c(entry: Mapping[str, Any], results: Mapping[str, Any],
                        c: RigConstants) -> float:
    temps = [float(p["temperature_c"]) for key in ("bias_v", "scale_v_per_dps2")
             for p in ex.temperature_points(entry, key)]
    temps = temps or ex.step_values(results.get("steps") or [], "temperature_c")
    return (max(temps) - min(temps)) if len(temps) >= 2 else c.temperature_span_c


def temperature_measurand(results: Mapping[str, Any], channel: str, key: str,
                          c: RigConstants) -> Measurand | None:
    """c_T = ĉ·(1 + e_therm) + e_reg  (V/°C or 1/°C).

    ``e_reg`` is the regression's statistical uncertainty (or, when the analysis gives no
    statistics, the branch hysteresis spread over the span, rectangular); ``e_therm`` is the
    relative error of the temperature span from the thermometer (√2·u_T/ΔT).
    """
    entry = ex.channel_entry(results, "temperature", channel)
    where = f"analysis.temperature.{channel}"
    value = ex.require_float(entry, key, where) if entry is not None else None
    if value is None:
        return None
    point_key, unit = TEMPERATURE_COEFFICIENTS[key]
    span = _temperature_span_c(entry, results, c)
    u_reg, source = _slope_std(entry, key, point_key)
    if u_reg is not None:
        reg = Input("regression", "bias/scale readings (regression)", 0.0, u_reg, "normal", unit,
                    source)
    else:
        hyst = ex.as_float(entry.get("hysteresis_v")) or 0.0
        if point_key == "scale_v_per_dps2":
            hyst = 0.0  # hysteresis is reported for the bias only
        reg = Input("regression", "hysteresis between branches", 0.0, hyst / span, "rectangular",
                    unit, "no regression statistics: branch difference over the span")
    inputs = (
        reg,
        _rel("thermometer", "temperature measurement", math.sqrt(2) * c.thermometer_uncertainty_c
             / span, f"{c.thermometer_uncertainty_c:g} °C per reading over {span:.1f} °C"),
    )

    def model(ops: Ops, x: Mapping[str, Any]) -> Any:
        return value * (1.0 + x["thermometer"]) + x["regression"]

    return Measurand(f"{key} {channel}", unit, model, inputs)
