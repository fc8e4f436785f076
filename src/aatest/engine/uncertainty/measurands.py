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
from aatest.engine.procedure.rig_description import Instruments
from aatest.engine.uncertainty import access as ex
from aatest.engine.uncertainty import components as comp
from aatest.engine.uncertainty.components import ARCSEC_RAD
from aatest.engine.uncertainty.declared import Basis, declared_encoder
from aatest.engine.uncertainty.evidence import Evidence, gather
from aatest.engine.uncertainty.gum import Input, Measurand, Ops

#: a slope needs three points to have a statistical uncertainty
MIN_REGRESSION_POINTS = 3

__all__ = ["ARCSEC_RAD", "RigConstants", "bias_measurand", "g_sensitivity_measurand",
           "scale_factor_measurand", "temperature_measurand"]


class RigConstants(BaseModel):
    """Stated accuracies of the rig that enter every budget (docs/method.md §1.2, §2).

    Built from the run's rig description by :meth:`from_results` (the ``instruments`` block of
    ``--rig``, or of an import's ``dataset.yaml``); ``instruments_stated`` is False when the
    description stated none and the documented defaults stand in (each basis says so).
    ``evidence`` holds what the recording itself shows (motion distortion, temperatures).
    """

    model_config = ConfigDict(frozen=True, extra="forbid", arbitrary_types_allowed=True)
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
    instruments: Instruments = Field(default_factory=Instruments)
    instruments_stated: bool = Field(False, description="the rig description stated them")
    evidence: Evidence = Field(default_factory=Evidence)
    #: encoder numbers not from the rig description: declared by the table plugin, or a
    #: default naming the missing declaration (:mod:`.declared`)
    encoder_basis: Basis = Field(default_factory=dict)

    @classmethod
    def from_results(cls, results: Mapping[str, Any], data: Any = None) -> RigConstants:
        """The constants of this run: its rig description's instruments and its recording.

        Parameters
        ----------
        results
            The results document; ``metadata.rig.instruments`` (or ``rig.instruments``) is the
            stated description.
        data
            The dataset the analyses ran on, for the measured components (None: none).
        """
        stated = ex.stated_instruments(results)
        instruments = Instruments.model_validate(stated) if stated is not None else Instruments()
        instruments, encoder_basis = declared_encoder(results, instruments)
        return cls(encoder_basis=encoder_basis,
                   position_accuracy_arcsec=instruments.encoder.accuracy_arcsec,
                   wobble_arcsec=instruments.table.wobble_arcsec,
                   orthogonality_arcsec=instruments.table.orthogonality_arcsec,
                   thermometer_uncertainty_c=instruments.thermometer.accuracy_c / math.sqrt(3.0),
                   instruments=instruments, instruments_stated=stated is not None,
                   evidence=gather(data))

    def source(self, what: str, cert: str = "") -> str:
        """``rig description: <what> (<cert>)``, or ``stated default: <what>`` without one."""
        if self.instruments_stated:
            return f"rig description: {what}" + (f" ({cert})" if cert else "")
        return f"stated default: {what} (the rig description states none)"


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
        comp.rel("fit_reference", "the fit: reference noise (residual)",
                 rel_fit * math.sqrt(1.0 - share**2),
                 f"measured: reference-noise part of the fit, {source}", kind="A"),
        comp.rel("fit_noise", "the fit: sensor noise (residual)", rel_fit * share,
                 f"measured: sensor-noise part of the fit, {noise_v * 1e3:.2f} mV RMS",
                 kind="A"),
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
        return [comp.not_evaluated("repeatability", "repeatability over repetitions",
                                   "the procedure has no repeated steps for this quantity", unit)]
    return [Input("repeatability", "repeatability over repetitions", 0.0, u / scale, "normal",
                  unit, f"measured: s/√n over {len(values)} repetitions", "A")]


def _inputs(inputs: Sequence[Input]) -> tuple[Input, ...]:
    return tuple(inputs)


def _sine_steps(results: Mapping[str, Any], entry: Mapping[str, Any]) -> list[str]:
    """Step ids the scale factor was calibrated from (all sine steps when not stated)."""
    listed = entry.get("steps")
    if isinstance(listed, Sequence) and not isinstance(listed, str) and listed:
        return [str(s) for s in listed]
    return [str(s.get("id")) for s in ex.steps_of_kind(results, "sine")]


def _scale_tc_per_c(results: Mapping[str, Any], channel: str) -> tuple[float, str]:
    """Relative scale temperature coefficient: measured in this run, else the datasheet limit."""
    temp = (ex.analysis(results, "temperature") or {}).get(channel) or {}
    measured = ex.as_float(temp.get("scale_coefficient_per_c"))
    if measured is not None:
        return abs(measured), f"measured scale TC {measured * 100:.4f} %/°C"
    limit = ex.as_float(ex.sensors(results).get(channel, {}).get("scale_temperature_limit_per_c"))
    limit = limit if limit is not None else 0.0005
    return limit, f"datasheet scale TC ≤ {limit * 100:g} %/°C"


def scale_factor_measurand(results: Mapping[str, Any], channel: str,
                           c: RigConstants) -> Measurand | None:
    """K = K̂·Π(1 + e_i) / ((1 + e_gain)·(1 + e_clk)²)  [V/(°/s²)].

    The measurand is the slope of the best straight line of logged output volts on the
    angular acceleration about the sensor's mounting axis over the sine records — for a sine,
    the in-phase fundamental-bin ratio — at the records' frequency, amplitude and temperature.
    Reference inputs (encoder accuracy and resolution, reference method, motion distortion, the
    fit), the axis (wobble, transverse, mounting), the logger (gain, resolution), the clock,
    temperature and repeatability each enter as a relative input.
    """
    entry = ex.channel_entry(results, "scale_factor", channel)
    where = f"analysis.scale_factor.{channel}"
    k_hat = ex.require_float(entry, "scale_v_per_dps2", where) if entry is not None else None
    if k_hat is None:
        return None
    noise_v, _ = ex.noise_rms_v(results, channel)
    amp_arcsec = _reference_amplitude_deg(results) * 3600.0
    steps = _sine_steps(results, entry)
    sine = [s for s in ex.steps_of_kind(results, "sine") if str(s.get("id")) in steps]
    accel = max(ex.step_values(sine, "accel_dps2") or [400.0])
    freqs = sorted(set(ex.step_values(sine, "frequency_hz")))
    samples = sum(ex.step_values(sine, "samples")) or c.record_samples
    chosen = str(entry.get("reference") or "fit")
    tc, tc_note = _scale_tc_per_c(results, channel)
    temp_input, at_temperature = comp.temperature(c, steps, tc, tc_note, "1")
    q_text = (f"logger {c.instruments.logger.bits} bit, q = "
              f"{c.instruments.logger.step_v * 1e6:.0f} µV")
    q_rel = c.instruments.logger.resolution_u_v * math.sqrt(2.0 / samples) / (abs(k_hat) * accel)
    inputs = [
        *_scale_fit_inputs(entry, k_hat, noise_v, results, c, where),
        comp.reference_method(results, steps, chosen),
        *comp.motion_distortion(c, steps),
        comp.encoder_accuracy(c, amp_arcsec),
        comp.encoder_resolution(c, amp_arcsec),
        comp.rel("clock", "synchronisation: clock rate (sync residual)", _sync_rate_rel(results),
                 "measured: rate of the fitted clock relation (sync analysis)"),
        comp.wobble(c),
        comp.transverse(c, results, channel),
        comp.mounting(c, results, channel),
        comp.logger_gain(c),
        comp.rel("logger_resolution", "logger resolution", q_rel,
                 f"{c.source(q_text)}; q/√12 over {samples:.0f} samples of the fit"),
        temp_input,
        *_repeat_input(entry, "scale_v_per_dps2", k_hat, "1"),
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
    """u of the mean over mountings (original/pivoted) when only their u are reported."""
    mountings = entry.get("mountings")
    if not isinstance(mountings, Mapping):
        return None
    us = [ex.as_float(m.get(u_key)) for m in mountings.values() if isinstance(m, Mapping)]
    known = [u for u in us if u is not None]
    if not known or len(known) != len(us):
        return None
    return math.sqrt(sum(u * u for u in known)) / len(known)


def _pooled_mountings(entry: Mapping[str, Any], key: str, u_key: str
                      ) -> tuple[float, float, int] | None:
    """Type A of the mean over every repetition of every mounting: (u, degrees of freedom, n).

    Each mounting reports its mean over r repetitions and u = s/√r; the within- and
    between-mounting sums of squares are pooled over all n = Σr values (the pivot changes
    nothing the quantity depends on), s² = SS/(n − 1), u = s/√n with n − 1 degrees of freedom.
    """
    mountings = entry.get("mountings")
    if not isinstance(mountings, Mapping):
        return None
    parts = []
    for m in mountings.values():
        if not isinstance(m, Mapping):
            continue
        value, u, reps = ex.as_float(m.get(key)), ex.as_float(m.get(u_key)), m.get("repetitions")
        if value is None or u is None or not isinstance(reps, int) or reps < 1:
            return None
        parts.append((value, u, reps))
    n = sum(r for _, _, r in parts)
    if not parts or n < ex.PAIR:
        return None
    grand = sum(v * r for v, _, r in parts) / n
    within = sum((r - 1) * r * u * u for _, u, r in parts)
    between = sum(r * (v - grand) ** 2 for v, _, r in parts)
    return math.sqrt((within + between) / (n - 1) / n), float(n - 1), n


def _static_statistics(results: Mapping[str, Any], entry: Mapping[str, Any], channel: str,
                       c: RigConstants, key: str, u_key: str, volts_per_unit: float,
                       unit: str) -> list[Input]:
    """Type A inputs of a static quantity: pooled over every repetition and mounting when the
    analysis reports them (noise, hysteresis and repeatability alike, with their degrees of
    freedom), else the analysis' own u, else sensor noise over the records plus repeatability."""
    pooled = _pooled_mountings(entry, key, u_key)
    if pooled is not None:
        u, dof, n = pooled
        return [Input("noise", "static means (noise, repeatability)", 0.0, u, "normal", unit,
                      f"measured: s/√n over {n} repetitions × mountings ({dof:.0f} degrees of "
                      "freedom)", "A", dof=dof)]
    stated = ex.as_float(entry.get(u_key)) or _mounting_u(entry, u_key)
    if stated is not None:
        return [Input("noise", "static means (noise, repeatability)", 0.0, stated, "normal",
                      unit, "measured: type A, from the analysis", "A")]
    reps = max(len(ex.repetition_values(entry, key)), 1)
    u_mean, note = _static_mean_std_v(results, channel, c, 2 * reps)
    return [Input("noise", "sensor noise", 0.0, u_mean / volts_per_unit, "normal", unit,
                  note, "A"),
            *_repeat_input(entry, key, 1.0, unit)]


def _bias_tc_v_per_c(results: Mapping[str, Any], channel: str) -> float:
    temp = (ex.analysis(results, "temperature") or {}).get(channel) or {}
    measured = ex.as_float(temp.get("bias_coefficient_v_per_c"))
    if measured is not None:
        return abs(measured)
    limit = ex.as_float(ex.sensors(results).get(channel, {}).get("bias_temperature_limit_v_per_c"))
    return limit or 0.0004


def _static_steps(results: Mapping[str, Any]) -> list[str]:
    return [str(s.get("id")) for s in ex.steps_of_kind(results, "static")]


def _bias_tc_note(results: Mapping[str, Any], channel: str) -> tuple[float, str]:
    tc = _bias_tc_v_per_c(results, channel)
    temp = (ex.analysis(results, "temperature") or {}).get(channel) or {}
    source = "measured" if ex.as_float(temp.get("bias_coefficient_v_per_c")) is not None \
        else "datasheet limit"
    return tc, f"{source} bias TC {tc * 1e3:.2f} mV/°C"


def bias_measurand(results: Mapping[str, Any], channel: str, c: RigConstants) -> Measurand | None:
    """b = (b̂ − e_off − e_res)/(1 + e_gain) + e_noise + e_temp + e_rep  [V].

    b̂ = (A+ + A−)/2 cancels the g-sensitivity and table tilt; the logger's offset and gain
    accuracy and its resolution enter in full (a gain error scales the whole ≈2.5 V reading).
    """
    entry = ex.channel_entry(results, "bias", channel)
    where = f"analysis.bias.{channel}"
    b_hat = ex.require_float(entry, "bias_v", where) if entry is not None else None
    if b_hat is None:
        return None
    tc, tc_note = _bias_tc_note(results, channel)
    temp_input, at_temperature = comp.temperature(c, _static_steps(results), tc, tc_note, "V")
    inputs = [
        *_static_statistics(results, entry, channel, c, "bias_v", "bias_u_v", 1.0, "V"),
        _static_disturbance(c, channel, 1.0, "V"),
        comp.logger_offset(c),
        comp.logger_gain(c),
        comp.logger_resolution_v(c),
        temp_input,
    ]

    def model(ops: Ops, x: Mapping[str, Any]) -> Any:
        logged = (b_hat - x["logger_offset"] - x["logger_resolution"]) / (1.0 + x["logger_gain"])
        return (logged + x["noise"] + x["disturbance"] + x["temperature"]
                + x.get("repeatability", 0.0))

    definition = (f"bias K0 of {channel}: output (V) at zero angular rate and acceleration, the "
                  f"mean of the +1 g and −1 g positions of the sensitive axis (g-sensitivity "
                  f"cancels), at {at_temperature}")
    return Measurand(f"bias {channel}", "V", model, _inputs(inputs), definition)


def _scale_input(results: Mapping[str, Any], channel: str, scale_rel_u: float | None) -> Input:
    """K's relative uncertainty: calibrated in this run, else its datasheet tolerance."""
    if scale_rel_u is not None:
        return _rel("scale", "scale factor", scale_rel_u, "relative u_c(K)/K of this calibration")
    tol_pct = ex.as_float(ex.sensors(results).get(channel, {}).get("scale_tolerance_pct")) or 1.0
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


def _dithered_resolution(results: Mapping[str, Any], channel: str, c: RigConstants,
                         k_v: float, unit: str) -> Input:
    """Logger resolution in a half-difference of means: averaged over the samples when the
    output noise dithers the converter (σ ≥ q/2), else one step q/√12."""
    lg = c.instruments.logger
    noise_v, source = ex.noise_rms_v(results, channel)
    samples = sum(ex.step_values(ex.steps_of_kind(results, "static"), "samples"))
    what = f"logger resolution q = {lg.step_v * 1e6:.0f} µV ({lg.bits} bit)"
    if noise_v >= lg.step_v / 2 and samples >= ex.PAIR:
        u_v = lg.resolution_u_v * math.sqrt(2.0 / samples)
        note = (f"{c.source(what)}; dithered by {noise_v * 1e3:.2f} mV noise ({source}): "
                f"q/√12 over {samples / 2:.0f} samples per sign")
    else:
        u_v, note = lg.resolution_u_v, f"{c.source(what)}; not dithered: q/√12"
    return Input("logger_resolution", "logger resolution", 0.0, u_v * math.sqrt(2.0) / (2 * k_v),
                 "normal", unit, note + ", of a half-difference over 2K")


def g_sensitivity_measurand(results: Mapping[str, Any], channel: str, c: RigConstants,
                            scale_rel_u: float | None) -> Measurand | None:
    """G = (Ĝ + e_noise + e_dist + e_temp + e_rep + e_res) / Π(1 + e_K, e_gain, e_tilt, e_mnt)
    in (°/s²)/g.

    Ĝ = (A+ − A−)/(2K): the half-difference carries the noise of both means and any bias
    drift between them (the logger offset cancels, its gain does not); dividing by K carries
    the scale factor's relative uncertainty (its datasheet tolerance when the run did not
    calibrate K, ``scale_rel_u=None``); a tilt of the table or of the mounting reduces the
    ±1 g projection by its cosine.
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
    tc, tc_note = _bias_tc_note(results, channel)
    static_ids = _static_steps(results)
    tilt = math.hypot(c.position_accuracy_arcsec, c.wobble_arcsec) * ARCSEC_RAD
    unit = "(°/s²)/g"
    inputs = [
        *_static_statistics(results, entry, channel, c, "g_sensitivity_dps2_per_g",
                            "g_sensitivity_u_dps2_per_g", k_v, unit),
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
    if len(points) >= MIN_REGRESSION_POINTS:
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
    return (max(temps) - min(temps)) if len(temps) >= ex.PAIR else c.temperature_span_c


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
