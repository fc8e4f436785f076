"""Measurement models and uncertainty budgets (GUM, k = 2) for the calibration certificate.

Each ``*_measurand`` function turns an analysis result plus rig constants into a
:class:`~aatest.metrology.uncertainty.gum.Measurand`: the final quantity's model with one input per
budget row (fit/reference noise, sensor noise, table position accuracy, wobble/orthogonality,
sync residual, environment temperature, repeatability over repetitions). Statistical inputs
come from the analysis (ci95, per-repetition values, measured noise); the rest are the rig's
stated accuracies (:class:`RigConstants`, docs/method.md §1.2). Quantities are propagated with
``uncertainties`` (first order) and checked against Monte Carlo in the tests.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from aatest.metrology.uncertainty import components as comp
from aatest.metrology.uncertainty.clock_window import clock_coverage_input
from aatest.metrology.uncertainty.components import ARCSEC_RAD
from aatest.metrology.uncertainty.gum import Input, Measurand, Ops
from aatest.metrology.uncertainty.rig_constants import RigConstants
from aatest.metrology.uncertainty.statistics import PAIR, ci_std, finite, finite_values
from aatest.results import RunResults
from aatest.results.bias import BiasChannel, BiasSetpoint, MountingBias
from aatest.results.scale_factor import ScaleFactorChannel
from aatest.results.temperature import TemperatureChannel

#: a slope needs three points to have a statistical uncertainty
MIN_REGRESSION_POINTS = 3

__all__ = ["ARCSEC_RAD", "RigConstants", "bias_measurand", "g_sensitivity_measurand",
           "scale_factor_measurand", "temperature_measurand"]


def _rel(name: str, label: str, u: float, note: str, dist: str = "normal") -> Input:
    return Input(name, label, 0.0, u, dist, "1", note)  # type: ignore[arg-type]


def _scale_fit_inputs(entry: ScaleFactorChannel, k_v: float, noise_v: float,
                      results: RunResults, c: RigConstants) -> list[Input]:
    """Split the fit's relative uncertainty into reference-noise and sensor-noise parts.

    The slope variance of a least-squares fit is proportional to the residual variance,
    which is the sum of reference-acceleration noise and sensor noise (in °/s²); each part
    of the budget gets its share of it.
    """
    coeffs = entry.coefficients
    a1 = finite(coeffs[1]) if len(coeffs) > 1 else None
    u_a1 = ci_std(entry.ci95[1] if len(entry.ci95) > 1 else None) if a1 else None
    u_k = finite(entry.scale_u_v_per_dps2) or ci_std(entry.scale_ci95)
    rmse = finite(entry.rmse_dps2)
    sine = results.steps_of_kind("sine")
    if u_k is not None:
        rel_fit, source = u_k / k_v, "from the analysis' u(K)"
    elif u_a1 is not None and a1:
        rel_fit, source = u_a1 / abs(a1), "from the fit's ci95 of a1"
    elif rmse is not None:
        peak = max(finite_values(s.accel_dps2 for s in sine) or [400.0])
        n = sum(s.samples for s in sine) or c.record_samples
        rel_fit, source = rmse / (peak * math.sqrt(n / 2.0)), "from RMSE and record length"
    else:
        return []
    share = min(1.0, (noise_v / k_v) / rmse) if rmse else 0.0
    return [
        comp.rel("fit_reference", "the fit: reference noise (residual)",
                 rel_fit * math.sqrt(1.0 - share**2),
                 f"measured: reference-noise part of the fit, {source}", kind="A"),
        comp.rel("fit_noise", "the fit: sensor noise (residual)", rel_fit * share,
                 f"measured: sensor-noise part of the fit, {noise_v * 1e3:.2f} mV RMS",
                 kind="A"),
    ]


def _reference_amplitude_deg(results: RunResults) -> float:
    """Typical sine position amplitude A = α/(2πf)² of the calibration records (deg)."""
    amps = finite_values(s.amplitude_deg for s in results.steps_of_kind("sine"))
    if amps:
        return float(sorted(amps)[len(amps) // 2])
    return 400.0 / (2 * math.pi) ** 2


def _sync_rate_rel(results: RunResults) -> float:
    """Relative clock-rate uncertainty left after the sync fit: σ_res·√(12/n) / T."""
    sync = results.analysis.sync
    residual_s = ((finite(sync.residual_rms_us) if sync else None) or 3.5) * 1e-6
    edges = float((sync.edges_used if sync else 0) or 6553.0)
    span_s = max(edges, 2.0) / 100.0  # 100 Hz sync pulse
    return residual_s * math.sqrt(12.0 / max(edges, 2.0)) / span_s


def _repeatability_not_evaluated(unit: str) -> Input:
    """The results state one value per channel, not one per repetition: no repeatability row
    of its own (the Type A of a static quantity pools the repetitions, see
    :func:`_static_statistics`)."""
    return comp.not_evaluated("repeatability", "repeatability over repetitions",
                              "the procedure has no repeated steps for this quantity", unit)


def _inputs(inputs: Sequence[Input]) -> tuple[Input, ...]:
    return tuple(inputs)


def _sine_steps(results: RunResults, entry: ScaleFactorChannel) -> list[str]:
    """Step ids the scale factor was calibrated from (all sine steps when not stated)."""
    if entry.steps:
        return list(entry.steps)
    return [s.id for s in results.steps_of_kind("sine")]


def _temperature_entry(results: RunResults, channel: str) -> TemperatureChannel | None:
    block = results.analysis.temperature
    return block.get(channel) if block else None


def _scale_tc_per_c(results: RunResults, channel: str) -> tuple[float, str]:
    """Relative scale temperature coefficient: measured in this run, else the datasheet limit."""
    temp = _temperature_entry(results, channel)
    measured = finite(temp.scale_coefficient_per_c) if temp else None
    if measured is not None:
        return abs(measured), f"measured scale TC {measured * 100:.4f} %/°C"
    limit = results.sensor(channel).scale_temperature_limit_per_c
    return limit, f"datasheet scale TC ≤ {limit * 100:g} %/°C"


def scale_factor_measurand(results: RunResults, channel: str, c: RigConstants,
                           level: ScaleFactorChannel | None = None) -> Measurand | None:
    """K = K̂·Π(1 + e_i) / ((1 + e_gain)·(1 + e_clk)²)  [V/(°/s²)].

    The measurand is the slope of the best straight line of logged output volts on the
    angular acceleration about the sensor's mounting axis over the sine records — for a sine,
    the in-phase fundamental-bin ratio — at the records' frequency, amplitude and temperature.
    Reference inputs (encoder accuracy and resolution, reference method, motion distortion, the
    fit), the axis (wobble, transverse, mounting), the logger (gain, resolution), the clock,
    temperature and repeatability each enter as a relative input. ``level`` is one of the
    channel's acceleration levels (default: the headline).
    """
    block = results.analysis.scale_factor
    entry = level if level is not None else (block.get(channel) if block else None)
    k_hat = finite(entry.scale_v_per_dps2) if entry is not None else None
    if entry is None or k_hat is None:
        return None
    noise_v, _ = comp.noise_rms_v(results, channel)
    amp_arcsec = _reference_amplitude_deg(results) * 3600.0
    steps = _sine_steps(results, entry)
    sine = [s for s in results.steps_of_kind("sine") if s.id in steps]
    accel = max(finite_values(s.accel_dps2 for s in sine) or [400.0])
    freqs = sorted(set(finite_values(s.frequency_hz for s in sine)))
    samples = sum(s.samples for s in sine) or c.record_samples
    chosen = entry.reference or "fit"
    tc, tc_note = _scale_tc_per_c(results, channel)
    temp_input, at_temperature = comp.temperature(c, steps, tc, tc_note, "1")
    q_text = (f"logger {c.instruments.logger.bits} bit, q = "
              f"{c.instruments.logger.step_v * 1e6:.0f} µV")
    q_rel = c.instruments.logger.resolution_u_v * math.sqrt(2.0 / samples) / (abs(k_hat) * accel)
    inputs = [
        *_scale_fit_inputs(entry, k_hat, noise_v, results, c),
        comp.reference_method(results, steps, chosen),
        *comp.motion_distortion(c, steps),
        comp.encoder_accuracy(c, amp_arcsec),
        comp.encoder_resolution(c, amp_arcsec),
        comp.rel("clock", "synchronisation: clock rate (sync residual)", _sync_rate_rel(results),
                 "measured: rate of the fitted clock relation (sync analysis)"),
        comp.wobble(c),
        comp.transverse(c, channel),
        comp.mounting(c, results, channel),
        comp.logger_gain(c),
        comp.rel("logger_resolution", "logger resolution", q_rel,
                 f"{c.source(q_text)}; q/√12 over {samples:.0f} samples of the fit"),
        temp_input,
        _repeatability_not_evaluated("1"),
    ]
    additive = [i.name for i in inputs if i.name not in ("clock", "logger_gain", "wobble",
                                                           "mounting")]

    def model(ops: Ops, x: Mapping[str, Any]) -> Any:
        terms = 1.0 + sum(x.get(k, 0.0) for k in additive)
        axis = (1.0 + x["wobble"]) * (1.0 + x["mounting"])
        return k_hat * terms / ((1.0 + x["logger_gain"]) * (1.0 + x["clock"]) ** 2 * axis)

    f_text = ", ".join(f"{f:g}" for f in freqs) or "?"
    definition = (f"scale factor of {channel}: slope of the best straight line of the logged "
                  f"output (V) on the angular acceleration (°/s²) about the sensor's mounting "
                  f"axis, i.e. the in-phase fundamental-bin ratio, at f = {f_text} Hz, peak α = "
                  f"{accel:g} °/s², reference '{chosen}', at {at_temperature}")
    return Measurand(f"scale factor {channel}", "V/(°/s²)", model, _inputs(inputs), definition)


def _static_mean_std_v(results: RunResults, channel: str, c: RigConstants,
                       records: int) -> tuple[float, str]:
    """Standard uncertainty of one static mean: σ / √(2·B·T) per record, over ``records``."""
    noise_v, source = comp.noise_rms_v(results, channel)
    static = results.steps_of_kind("static")
    duration_s = min(finite_values(s.duration_s for s in static) or [c.static_record_s])
    independent = 2.0 * c.noise_bandwidth_hz * duration_s * max(records, 1)
    note = f"{noise_v * 1e3:.2f} mV RMS ({source}), {records}×{duration_s:g} s, B = " \
           f"{c.noise_bandwidth_hz:g} Hz"
    return noise_v / math.sqrt(independent), note


#: a static quantity of one mounting: its mean and that mean's standard uncertainty
MountingStatistic = Callable[[MountingBias], tuple[float | None, float | None]]


def _bias_of(m: MountingBias) -> tuple[float | None, float | None]:
    return m.bias_v, m.bias_u_v


def _g_sensitivity_of(m: MountingBias) -> tuple[float | None, float | None]:
    return m.g_sensitivity_dps2_per_g, m.g_sensitivity_u_dps2_per_g


def _mounting_u(entry: BiasChannel, statistic: MountingStatistic) -> float | None:
    """u of the mean over mountings (original/pivoted) when only their u are reported."""
    us = [finite(statistic(m)[1]) for m in entry.mountings.values()]
    known = [u for u in us if u is not None]
    if not known or len(known) != len(us):
        return None
    return math.sqrt(sum(u * u for u in known)) / len(known)


def _pooled_mountings(entry: BiasChannel, statistic: MountingStatistic
                      ) -> tuple[float, float, int] | None:
    """Type A of the mean over every repetition of every mounting: (u, degrees of freedom, n).

    Each mounting reports its mean over r repetitions and u = s/√r; the within- and
    between-mounting sums of squares are pooled over all n = Σr values (the pivot changes
    nothing the quantity depends on), s² = SS/(n − 1), u = s/√n with n − 1 degrees of freedom.
    """
    parts = []
    for m in entry.mountings.values():
        value, u = (finite(x) for x in statistic(m))
        if value is None or u is None or m.repetitions is None or m.repetitions < 1:
            return None
        parts.append((value, u, m.repetitions))
    n = sum(r for _, _, r in parts)
    if not parts or n < PAIR:
        return None
    grand = sum(v * r for v, _, r in parts) / n
    within = sum((r - 1) * r * u * u for _, u, r in parts)
    between = sum(r * (v - grand) ** 2 for v, _, r in parts)
    return math.sqrt((within + between) / (n - 1) / n), float(n - 1), n


@dataclass(frozen=True)
class _StaticQuantity:
    """A static quantity of a bias result: its per-mounting statistic, the Type A the
    analysis states for the channel (if any), its unit and volts per unit."""

    statistic: MountingStatistic
    stated_u: float | None
    volts_per_unit: float
    unit: str


def _static_statistics(results: RunResults, entry: BiasChannel, channel: str,
                       c: RigConstants, quantity: _StaticQuantity) -> list[Input]:
    """Type A inputs of a static quantity: pooled over every repetition and mounting when the
    analysis reports them (noise, hysteresis and repeatability alike, with their degrees of
    freedom), else the analysis' own u, else sensor noise over the records."""
    unit = quantity.unit
    pooled = _pooled_mountings(entry, quantity.statistic)
    if pooled is not None:
        u, dof, n = pooled
        return [Input("noise", "static means (noise, repeatability)", 0.0, u, "normal", unit,
                      f"measured: s/√n over {n} repetitions × mountings ({dof:.0f} degrees of "
                      "freedom)", "A", dof=dof)]
    stated = finite(quantity.stated_u) or _mounting_u(entry, quantity.statistic)
    if stated is not None:
        return [Input("noise", "static means (noise, repeatability)", 0.0, stated, "normal",
                      unit, "measured: type A, from the analysis", "A")]
    u_mean, note = _static_mean_std_v(results, channel, c, 2)
    return [Input("noise", "sensor noise", 0.0, u_mean / quantity.volts_per_unit, "normal", unit,
                  note, "A"),
            _repeatability_not_evaluated(unit)]


def _bias_tc_note(results: RunResults, channel: str) -> tuple[float, str]:
    """|bias TC| (V/°C): measured in this run, else the sensor's datasheet limit."""
    temp = _temperature_entry(results, channel)
    measured = finite(temp.bias_coefficient_v_per_c) if temp else None
    if measured is not None:
        return abs(measured), f"measured bias TC {abs(measured) * 1e3:.2f} mV/°C"
    tc = results.sensor(channel).bias_temperature_limit_v_per_c
    return tc, f"datasheet limit bias TC {tc * 1e3:.2f} mV/°C"


def _static_steps(results: RunResults, temperature_c: float | None = None) -> list[str]:
    """The static steps (at one chamber set-point when ``temperature_c`` is given)."""
    return [s.id for s in results.steps_of_kind("static")
            if temperature_c is None or s.temperature_c == temperature_c]


def bias_measurand(results: RunResults, channel: str, c: RigConstants,
                   setpoint: BiasSetpoint | None = None) -> Measurand | None:
    """b = (b̂ − e_off − e_res)/(1 + e_gain) + e_noise + e_temp + e_rep  [V].

    b̂ = (A+ + A−)/2 cancels the g-sensitivity and table tilt; the logger's offset and gain
    accuracy and its resolution enter in full (a gain error scales the whole ≈2.5 V reading).
    ``setpoint`` is the bias at one chamber set-point (default: the headline).
    """
    entry = setpoint if setpoint is not None else _bias_entry(results, channel)
    b_hat = finite(entry.bias_v) if entry is not None else None
    if entry is None or b_hat is None:
        return None
    tc, tc_note = _bias_tc_note(results, channel)
    steps = _static_steps(results, getattr(entry, "temperature_c", None))  # its set-point's
    temp_input, at_temperature = comp.temperature(c, steps, tc, tc_note, "V")
    inputs = [
        *_static_statistics(results, entry, channel, c,
                            _StaticQuantity(_bias_of, entry.bias_u_v, 1.0, "V")),
        _static_disturbance(c, channel, 1.0, "V"),
        comp.logger_offset(c),
        comp.logger_gain(c),
        comp.logger_resolution_v(c),
        temp_input,
    ]
    clock = clock_coverage_input(results, channel, steps, "mean")
    if clock is not None:  # a record whose clock fit covers part of it (a finite table log)
        inputs.append(clock)

    def model(ops: Ops, x: Mapping[str, Any]) -> Any:
        logged = (b_hat - x["logger_offset"] - x["logger_resolution"]) / (1.0 + x["logger_gain"])
        return (logged + x["noise"] + x["disturbance"] + x["temperature"]
                + x.get("repeatability", 0.0) + x.get("clock_coverage", 0.0))

    definition = (f"bias K0 of {channel}: output (V) at zero angular rate and acceleration, the "
                  f"mean of the +1 g and −1 g positions of the sensitive axis (g-sensitivity "
                  f"cancels), at {at_temperature}")
    return Measurand(f"bias {channel}", "V", model, _inputs(inputs), definition)


def _bias_entry(results: RunResults, channel: str) -> BiasChannel | None:
    block = results.analysis.bias
    return block.get(channel) if block else None


def _scale_input(results: RunResults, channel: str, scale_rel_u: float | None) -> Input:
    """K's relative uncertainty: calibrated in this run, else its datasheet tolerance."""
    if scale_rel_u is not None:
        return _rel("scale", "scale factor", scale_rel_u, "relative u_c(K)/K of this calibration")
    tol_pct = results.sensor(channel).scale_tolerance_pct
    return _rel("scale", "scale factor", tol_pct / 100.0,
                f"nominal K, datasheet ±{tol_pct:g} % (not calibrated in this run)", "rectangular")


def _static_disturbance(c: RigConstants, channel: str, scale: float, unit: str) -> Input:
    """Residual of the strongest periodic line (e.g. the motor band) in the static means:
    at most V/(π·f·T) per record, the same in every record when the timing repeats — so
    rectangular, not averaged over records."""
    line = c.evidence.static_line_bound_v(channel, _static_ids(c))
    if line is None:
        return comp.not_evaluated("disturbance", "periodic disturbance in the static means",
                                  "no static record at hand", unit)
    return Input("disturbance", "periodic disturbance in the static means", 0.0,
                 line.residual_bound_v * scale, "rectangular", unit,
                 f"measured: strongest line {line.amplitude_v * 1e3:.2f} mV at "
                 f"{line.frequency_hz:.1f} Hz; ≤ V/(π·f·T) of it stays in a record mean")


def _static_ids(c: RigConstants) -> list[str]:
    return list(c.evidence.static_lines)


def _drift_between_records(c: RigConstants, steps: list[str], tc: float, tc_note: str,
                           k_v: float, unit: str) -> Input:
    """Bias drift between the +1 g and −1 g records: TC × the logged temperature's spread
    between records (a constant thermometer error cancels in the difference)."""
    logged = c.evidence.temperature_over(steps)
    if logged is None:
        lab = c.instruments.lab
        return Input("temperature", "temperature drift between the ±1 g records", 0.0,
                     tc * lab.temperature_tolerance_c / (2 * k_v), "rectangular", unit,
                     f"not logged: {c.source(f'lab tolerance ±{lab.temperature_tolerance_c:g} °C')}"
                     f" × {tc_note}, over 2K")
    spread_c = max(logged.std_c, 0.01 / math.sqrt(12.0))  # the log's 0.01 °C resolution
    return Input("temperature", "temperature drift between the ±1 g records", 0.0,
                 tc * math.sqrt(2.0) * spread_c / (2 * k_v), "normal", unit,
                 f"measured: spread of the logged temperature over the records "
                 f"{spread_c:.3f} °C × {tc_note}, √2 over 2K")


def _dithered_resolution(results: RunResults, channel: str, c: RigConstants,
                         k_v: float, unit: str) -> Input:
    """Logger resolution in a half-difference of means: averaged over the samples when the
    output noise dithers the converter (σ ≥ q/2), else one step q/√12."""
    lg = c.instruments.logger
    noise_v, source = comp.noise_rms_v(results, channel)
    samples = sum(s.samples for s in results.steps_of_kind("static"))
    what = f"logger resolution q = {lg.step_v * 1e6:.0f} µV ({lg.bits} bit)"
    if noise_v >= lg.step_v / 2 and samples >= PAIR:
        u_v = lg.resolution_u_v * math.sqrt(2.0 / samples)
        note = (f"{c.source(what)}; dithered by {noise_v * 1e3:.2f} mV noise ({source}): "
                f"q/√12 over {samples / 2:.0f} samples per sign")
    else:
        u_v, note = lg.resolution_u_v, f"{c.source(what)}; not dithered: q/√12"
    return Input("logger_resolution", "logger resolution", 0.0, u_v * math.sqrt(2.0) / (2 * k_v),
                 "normal", unit, note + ", of a half-difference over 2K")


def g_sensitivity_measurand(results: RunResults, channel: str, c: RigConstants,
                            scale_rel_u: float | None) -> Measurand | None:
    """G = (Ĝ + e_noise + e_dist + e_temp + e_rep + e_res) / Π(1 + e_K, e_gain, e_tilt, e_mnt)
    in (°/s²)/g.

    Ĝ = (A+ − A−)/(2K): the half-difference carries the noise of both means and any bias
    drift between them (the logger offset cancels, its gain does not); dividing by K carries
    the scale factor's relative uncertainty (its datasheet tolerance when the run did not
    calibrate K, ``scale_rel_u=None``); a tilt of the table or of the mounting reduces the
    ±1 g projection by its cosine.
    """
    entry = _bias_entry(results, channel)
    g_hat = finite(entry.g_sensitivity_dps2_per_g) if entry is not None else None
    if entry is None or g_hat is None:
        return None
    k_v = (finite(entry.scale_v_per_dps2_used)
           or results.sensor(channel).nominal_scale_v_per_dps2)
    tc, tc_note = _bias_tc_note(results, channel)
    static_ids = _static_steps(results)
    tilt = math.hypot(c.position_accuracy_arcsec, c.wobble_arcsec) * ARCSEC_RAD
    unit = "(°/s²)/g"
    inputs = [
        *_static_statistics(results, entry, channel, c,
                            _StaticQuantity(_g_sensitivity_of, None, k_v, unit)),
        _static_disturbance(c, channel, 1.0 / k_v, unit),
        _drift_between_records(c, static_ids, tc, tc_note, k_v, unit),
        _dithered_resolution(results, channel, c, k_v, unit),
        _scale_input(results, channel, scale_rel_u),
        comp.logger_gain(c),
        Input("tilt", "table position / wobble (tilt of gravity)", 0.0, tilt, "cosine_error", "1",
              c.source("encoder accuracy and wobble") + ", cos ε − 1 of the gravity projection"),
        comp.mounting(c, results, channel),
    ]

    def model(ops: Ops, x: Mapping[str, Any]) -> Any:
        g = (g_hat + x["noise"] + x["disturbance"] + x["temperature"]
             + x.get("repeatability", 0.0) + x["logger_resolution"])
        chain = (1.0 + x["scale"]) * (1.0 + x["logger_gain"])
        return g / (chain * (1.0 + x["tilt"]) * (1.0 + x["mounting"]))

    definition = (f"g-sensitivity of {channel}: change of the output per g of specific force "
                  f"along the sensitive axis, expressed as angular acceleration ((°/s²)/g) "
                  f"through K = {k_v:.6g} V/(°/s²): (A+ − A−)/(2K) of the ±1 g positions")
    return Measurand(f"g-sensitivity {channel}", unit, model, _inputs(inputs), definition)


def _paired(temperatures_c: Sequence[float] | None, values: Sequence[float] | None
            ) -> list[tuple[float, float]]:
    """(temperature °C, value) pairs of two columns of equal length, finite ones only."""
    if not temperatures_c or not values or len(temperatures_c) != len(values):
        return []
    return [(t, v) for t, v in zip(temperatures_c, values, strict=True)
            if finite(t) is not None and finite(v) is not None]


def _bias_points(entry: TemperatureChannel) -> list[tuple[float, float]]:
    return _paired(entry.temperatures_c, entry.bias_v)


def _scale_points(entry: TemperatureChannel) -> list[tuple[float, float]]:
    values = entry.scale_v_per_dps2
    temps = next((t for t in (entry.scale_temperatures_c, entry.temperatures_c)
                  if t is not None and len(t) == len(values or [])), None)
    return _paired(temps, values)


@dataclass(frozen=True)
class TemperatureCoefficient:
    """One temperature coefficient of a temperature result: how to read it and its points."""

    unit: str
    value: Callable[[TemperatureChannel], float | None]
    stated_u: Callable[[TemperatureChannel], float | None]
    ci95: Callable[[TemperatureChannel], list[float] | None]
    points: Callable[[TemperatureChannel], list[tuple[float, float]]]
    #: the coefficient is relative (1/°C): the readings are normalised by their mean
    relative: bool


#: the two coefficients of a temperature result, by their results.json name
TEMPERATURE_COEFFICIENTS: dict[str, TemperatureCoefficient] = {
    "bias_coefficient_v_per_c": TemperatureCoefficient(
        "V/°C", lambda e: e.bias_coefficient_v_per_c, lambda e: e.bias_coefficient_u_v_per_c,
        lambda e: e.bias_coefficient_ci95_v_per_c, _bias_points, relative=False),
    "scale_coefficient_per_c": TemperatureCoefficient(
        "1/°C", lambda e: e.scale_coefficient_per_c, lambda e: e.scale_coefficient_u_per_c,
        lambda e: e.scale_coefficient_ci95_per_c, _scale_points, relative=True),
}


def _slope_std(entry: TemperatureChannel, coefficient: TemperatureCoefficient
               ) -> tuple[float | None, str]:
    """Standard uncertainty of a temperature slope: ci95, else a regression over the points."""
    from scipy.stats import linregress

    stated = finite(coefficient.stated_u(entry))
    if stated is not None:
        return stated, "from the analysis' u"
    u = ci_std(coefficient.ci95(entry))
    if u is not None:
        return u, "from the analysis' ci95"
    points = coefficient.points(entry)
    if len(points) >= MIN_REGRESSION_POINTS:
        t = [p[0] for p in points]
        y = [p[1] for p in points]
        if coefficient.relative:  # relative coefficient: normalise by the mean
            mean = sum(y) / len(y)
            y = [v / mean for v in y]
        return float(linregress(t, y).stderr), f"regression over {len(points)} temperature points"
    return None, ""


def _temperature_span_c(entry: TemperatureChannel, results: RunResults,
                        c: RigConstants) -> float:
    temps = [t for t, _ in [*_bias_points(entry), *_scale_points(entry)]]
    temps = temps or finite_values(s.temperature_c for s in results.steps)
    return (max(temps) - min(temps)) if len(temps) >= PAIR else c.temperature_span_c


def temperature_measurand(results: RunResults, channel: str, key: str,
                          c: RigConstants) -> Measurand | None:
    """c_T = ĉ·(1 + e_therm) + e_reg  (V/°C or 1/°C).

    ``key`` names the coefficient (:data:`TEMPERATURE_COEFFICIENTS`). ``e_reg`` is the
    regression's statistical uncertainty (or, when the analysis gives no statistics, the
    branch hysteresis spread over the span, rectangular); ``e_therm`` is the relative error of
    the temperature span from the thermometer (√2·u_T/ΔT).
    """
    entry = _temperature_entry(results, channel)
    coefficient = TEMPERATURE_COEFFICIENTS[key]
    value = finite(coefficient.value(entry)) if entry is not None else None
    if entry is None or value is None:
        return None
    unit = coefficient.unit
    span = _temperature_span_c(entry, results, c)
    u_reg, source = _slope_std(entry, coefficient)
    if u_reg is not None:
        reg = Input("regression", "bias/scale readings (regression)", 0.0, u_reg, "normal", unit,
                    source)
    else:
        # hysteresis is reported for the bias only
        hyst = 0.0 if coefficient.relative else (finite(entry.hysteresis_v) or 0.0)
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
