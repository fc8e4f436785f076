"""Uncertainty of the dynamic results: FRF gain/phase per point and pivoted misalignment angles.

FRF (docs/method.md §4.4): at the excitation bin of an N-sample coherent record, white output noise
of power σ² adds a complex error whose radial and tangential parts both have relative standard
deviation 1/√(N·SNR) (SNR = fundamental power over noise power); the reference amplitude
A = α/(2πf)² is known to the table's position accuracy, which matters most at high f where A
is small; the logger alignment (sync residual) shifts the phase by 360·f·δt degrees.

Misalignment (docs/method.md §4.5): δ = (δ_e − δ_ep)/2 with δ_e = arcsin(|ΔA|/|A_z|); the
cross-response noise at the bin, σ_v·√(2/N), enters through the arcsine; wobble differs between
mountings and does not cancel, orthogonality is common to both and cancels in the difference.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, Literal

from aatest.metrology.uncertainty import components as comp
from aatest.metrology.uncertainty.gum import Input, Measurand, Ops
from aatest.metrology.uncertainty.measurands import RigConstants
from aatest.metrology.uncertainty.statistics import ResultsContractError, finite, finite_values
from aatest.results import RunResults
from aatest.results.frf import FrfPoint

#: the two budgets of an FRF point: the gain (radial part of the ratio's noise) and the phase
#: (tangential part)
FrfPart = Literal["gain", "phase"]

#: an offset u below this means the latch times aligned the loggers (else: one sample only)
LATCHED_OFFSET_U_S = 1e-4
#: misalignment scenario → (original, pivoted) set labels (docs/interfaces.md §5)
SCENARIO_SETS: dict[str, tuple[str, str]] = {"1": ("A", "B"), "2": ("C", "D"), "3": ("E", "F"),
                                             "4": ("G", "H")}


def _record_samples(results: RunResults, c: RigConstants) -> float:
    """Samples of the longest sine record (an FRF point does not state its own)."""
    sine = [s.samples for s in results.steps_of_kind("sine")]
    return float(max(sine)) if sine else float(c.record_samples)


def _bin_noise(point: FrfPoint, results: RunResults, c: RigConstants,
               part: FrfPart, channel: str = "") -> tuple[float, str]:
    """Relative (gain) or radian (phase) standard uncertainty of the bin ratio Y/X, and its basis.

    Measured next to the bin: by the FRF analysis on the ratio itself (``u_local_rel``: output
    and reference together, so content common to both — motion the sensor follows — cancels as
    at the bin, and a far line's leakage enters with the sensor's response at the line); else
    from the recording, output and reference apart (each √(mean |X_k|²/2)/|X_1| over nearby
    bins, in quadrature); else the FRF analysis' own ``u_gain_db`` / ``u_phase_deg``; else
    white noise at the bin from the SNRs, 1/√(N·SNR) each.
    """
    ratio = finite(point.u_local_rel)
    if ratio is not None:
        return ratio, (f"noise of the output/reference ratio next to the bin (bins 3–40 away) "
                       f"in the recording: {ratio * 100:.4f} % of the fundamental")
    local = c.evidence.bin_noise.get(point.step)
    if local is not None and channel in local.channels_rel:
        out, ref = local.channels_rel[channel], local.table_rel
        return (math.hypot(out, ref), f"noise next to the bin in the recording: output "
                f"{out * 100:.4f} %, reference {ref * 100:.4f} % of the fundamental")
    stated = finite(point.u_gain_db if part == "gain" else point.u_phase_deg)
    if stated is not None:
        if part == "gain":
            return stated * math.log(10.0) / 20.0, "u from the FRF analysis (u_gain_db)"
        return stated * math.pi / 180.0, "u from the FRF analysis (u_phase_deg)"
    n = _record_samples(results, c)
    parts = {"snr_db": finite(point.snr_db), "table_snr_db": finite(point.table_snr_db)}
    rel2 = sum(1.0 / (n * 10.0 ** (db / 10.0)) for db in parts.values() if db is not None)
    shown = ", ".join(f"{k} {v:.1f}" for k, v in parts.items() if v is not None) or "no SNR"
    return math.sqrt(rel2), f"1/√(N·SNR) of output and reference ({shown})"


#: why an FRF point has no between-record repeatability row (its within-record part is measured)
_REPEAT_REASON = ("one record per frequency. The scatter within the record (noise, the motor "
                  "band's dither of the hysteresis from cycle to cycle) is in the noise row; "
                  "a band line within a bin of a harmonic of f dithers every cycle alike, and "
                  "its effect, constant over the record, shows only between records")
#: the bins either side of the fundamental whose ratio noise is ``u_local_rel`` (the FRF analysis)
_NEAR_BIN_FIRST, _NEAR_BIN_LAST = 3, 40


def _noise_input(point: FrfPoint, results: RunResults, c: RigConstants,
                 part: FrfPart, channel: str, unit: str) -> Input:
    """The ``noise`` input of a gain (relative) or phase (rad) budget: Type A of the ratio.

    Two evaluations from the record, the larger governs (each blind where the other sees):

    - the spread of the FRF analysis' Hann-weighted segment ratios (``u_segments_*``, with
      their overlap-corrected degrees of freedom): everything that varies from segment to
      segment — noise, and the cycle-to-cycle scatter of the sensor's hysteresis dithered by
      the motor band — but not content closer to the fundamental than about a bin of the
      record, which every segment sees alike;
    - the ratio's noise in the bins 3–40 away (:func:`_bin_noise`, ``u_local_rel``): the
      density of whatever lies near the fundamental (intermodulation of the motor band's
      tones through the hysteresis included) taken as what sits at it, with one degree of
      freedom per bin (:func:`_neighbour_bins`); the rectangular bins also carry the band's
      1/Δ leakage, which the Hann segments do not (there it errs high).

    Results without segments (older analyses) use the second alone.
    """
    noise, basis = _bin_noise(point, results, c, part, channel)
    segment = finite(point.u_segments_gain_rel if part == "gain" else point.u_segments_phase_rad)
    dof = finite(point.segments_dof)
    if segment is None or not dof:
        return Input("noise", "sensor and reference noise (at the bin)", 0.0, noise, "normal",
                     unit, "measured: " + basis, "A")
    local_dof = (_neighbour_bins(point, results, c)
                 if finite(point.u_local_rel) is not None else math.inf)
    count, cycles = point.segments, point.cycles_per_segment
    what = "radial" if part == "gain" else "tangential"
    spread = (f"{what} spread of the ratio over {count} Hann-weighted segments of {cycles} "
              f"cycles, 50 % overlap: standard error of their mean {segment * 100:.4f} % "
              f"(overlap-corrected, ν = {dof:.1f})")
    label = "noise and within-record scatter (at the fundamental)"
    if segment >= noise:
        return Input("noise", label, 0.0, segment, "normal", unit,
                     f"measured, the larger of two: {spread}; {basis}", "A", dof=dof)
    return Input("noise", label, 0.0, noise, "normal", unit,
                 f"measured, the larger of two: {basis} (ν = {local_dof:.0f}, one radial and "
                 f"one tangential part per bin); {spread}", "A", dof=local_dof)


def _neighbour_bins(point: FrfPoint, results: RunResults, c: RigConstants) -> float:
    """How many bins ``u_local_rel`` averages (3–40 either side of the fundamental's bin,
    harmonic bins and DC left out): its degrees of freedom, one per bin for each part."""
    n = _record_samples(results, c)
    fs = finite(point.sample_rate_hz) or c.sample_rate_hz
    f_hz = finite(point.frequency_hz) or 0.0
    cycles = max(round(f_hz * n / fs), 1)
    offsets = range(_NEAR_BIN_FIRST, _NEAR_BIN_LAST + 1)
    near = [cycles + s * k for k in offsets for s in (-1, 1)]
    return float(sum(1 for b in near if 0 < b < n / 2 and b % cycles != 0))


def _point_temperature(point: FrfPoint, results: RunResults, c: RigConstants,
                       channel: str) -> tuple[Input, str]:
    tc = results.sensor(channel).scale_temperature_limit_per_c
    return comp.temperature(c, [point.step] if point.step else None, tc,
                            f"datasheet scale TC ≤ {tc * 100:g} %/°C", "1")


def _point_definition(kind: FrfPart, point: FrfPoint, channel: str, at: str) -> str:
    f_hz, accel = point.frequency_hz, point.accel_dps2
    what = ("gain: 20·log10 of the magnitude (dB re 1 V/(°/s²))" if kind == "gain" else
            "phase: argument (°, output lagging negative)")
    return (f"FRF {what} of the complex ratio of the fundamentals of the logged output of "
            f"{channel} (V, through the logger's pre-sample filter) and of the angular "
            f"acceleration about the sensor's mounting axis, in the steady state at "
            f"f = {f_hz:g} Hz, peak α = {accel:g} °/s², at {at}; the expectation over the "
            f"table's motor band, which dithers the sensor's hysteresis from cycle to cycle "
            f"(estimated by the mean of the ratios of Hann-weighted segments of whole cycles)")


def frf_gain_measurand(point: FrfPoint, results: RunResults,
                       c: RigConstants, channel: str = "") -> Measurand | None:
    """G = Ĝ + 20·log10((1 + e_out)·Π(1 + e_ref) / ((1 + e_gain)·(1 + e_tilt)·(1 + e_mnt)))  [dB].

    Reference inputs: encoder accuracy and resolution over the position amplitude (which
    dominate at high f, where the amplitude is small), the estimator's method error at the
    bin, the motion's distortion (THD of the table estimate); then the axis, the logger's gain
    and temperature.
    """
    gain, f_hz, accel = finite(point.gain_db), finite(point.frequency_hz), finite(point.accel_dps2)
    if gain is None or not f_hz or not accel:
        return None
    amp_arcsec = abs(accel) / (2 * math.pi * f_hz) ** 2 * 3600.0
    noise = _noise_input(point, results, c, "gain", channel, "1")
    fs = finite(point.sample_rate_hz) or c.sample_rate_hz
    method = (2 * math.pi * f_hz / fs) ** 2 / 12.0
    thd = finite(point.table_thd)
    temp_input, at = _point_temperature(point, results, c, channel)
    inputs = (
        noise,
        comp.encoder_accuracy(c, amp_arcsec),
        comp.encoder_resolution(c, amp_arcsec),
        comp.rel("reference_method", "reference: method error (table estimate at the bin)",
                 method, f"(ωT)²/12 = {method:.2e} of the second difference at f, T = 1/{fs:g} s",
                 "rectangular"),
        comp.rel("motion_distortion", "reference: motion distortion (THD)",
                 (thd or 0.0) ** 2,
                 f"measured: THD of the table acceleration {(thd or 0.0) * 100:.3f} % "
                 "(FRF analysis); a coherent bin sees it only as THD²", "rectangular")
        if thd is not None else comp.not_evaluated("motion_distortion",
                                                   "reference: motion distortion (THD)",
                                                   "the FRF analysis states no table THD"),
        comp.wobble(c),
        comp.transverse(c, channel),
        comp.mounting(c, results, channel),
        comp.logger_gain(c),
        temp_input,
        comp.not_evaluated("repeatability", "repeatability between records", _REPEAT_REASON),
    )
    additive = ("encoder_accuracy", "encoder_resolution", "reference_method", "motion_distortion",
                "transverse", "temperature", "repeatability")

    def model(ops: Ops, x: Mapping[str, Any]) -> Any:
        reference = (1.0 + x["wobble"]) * (1.0 + x["mounting"]) * (1.0 + x["logger_gain"])
        terms = 1.0 + sum(x[k] for k in additive)
        return gain + 20.0 * ops.log10((1.0 + x["noise"]) * terms / reference)

    return Measurand(f"FRF gain at {f_hz:.4f} Hz", "dB", model, inputs,
                     _point_definition("gain", point, channel, at))


def _sync_offset_s(results: RunResults, point: FrfPoint) -> tuple[float, str]:
    """Standard uncertainty of the logger alignment of the point's record and its basis."""
    sync = results.analysis.sync
    residual_us = (finite(sync.residual_rms_us) if sync else None) or 3.5
    edges = float((sync.edges_used if sync else 0) or 6553.0)
    u = residual_us * 1e-6 * math.sqrt(4.0 / max(edges, 2.0))
    note = (f"measured: {residual_us:g} µs RMS clock-relation residual over {edges:.0f} edges "
            "(offset of the fitted relation at the record's centre)")
    for entry in (sync.steps if sync else []):
        if entry.step != point.step:
            continue
        stated = finite(entry.offset_u_s)
        if not entry.latched and stated is not None:
            return stated, (
                f"measured without latch times: each edge known only to the table "
                f"sample that registered it; alignment at the record's centre "
                f"uniform over the lines through all {entry.edges_used} edge "
                f"intervals and the trigger, u = {stated * 1e6:.0f} µs (not "
                f"T/√12/√N: both loggers sample on one grid, so the edges' "
                f"quantisation errors are not independent); drift from the "
                f"{entry.drift_source or 'edges'}, u = {float(entry.drift_u_ppm):.2g} ppm")
        if stated is not None and stated < LATCHED_OFFSET_U_S:
            return stated, ("measured: the clock alignment's own standard uncertainty, from the "
                            "freeze-pulse latch times of this record")
    return u, note


def frf_phase_measurand(point: FrfPoint, results: RunResults,
                        c: RigConstants, channel: str = "") -> Measurand | None:
    """φ = φ̂ + (e_noise + e_enc + e_thd)·180/π − 360·f·(δt_sync + δt_timing) + e_rep  [deg]."""
    phase, f_hz = finite(point.phase_deg), finite(point.frequency_hz)
    if phase is None or not f_hz:
        return None
    noise = _noise_input(point, results, c, "phase", channel, "rad")
    u_sync, sync_note = _sync_offset_s(results, point)
    _, at = _point_temperature(point, results, c, channel)
    thd = finite(point.table_thd)
    inputs = (
        noise,
        Input("encoder_accuracy", "reference: encoder accuracy", 0.0, 0.0, "normal", "rad",
              "a position-periodic encoder error of a sine motion is a function of the "
              "motion's phase: it adds harmonics and in-phase content at the fundamental, no "
              "phase (its gain share is in the gain budget)"),
        Input("motion_distortion", "reference: motion distortion (THD)", 0.0, (thd or 0.0) ** 2,
              "rectangular", "rad",
              f"measured: THD of the table acceleration {(thd or 0.0) * 100:.3f} % (FRF "
              "analysis); a coherent bin sees it only as THD², in any direction")
        if thd is not None else comp.not_evaluated("motion_distortion",
                                                   "reference: motion distortion (THD)",
                                                   "the FRF analysis states no table THD", "rad"),
        Input("sync", "synchronisation: logger alignment", 0.0, u_sync, "normal", "s",
              sync_note),
        Input("timing", "synchronisation: logger timing against the latch", 0.0,
              c.instruments.logger.timing_accuracy_us * 1e-6, "rectangular", "s",
              c.source(f"logger timing accuracy ±{c.instruments.logger.timing_accuracy_us:g} µs",
                       c.instruments.logger.cert_text()) + "; enters as 360·f·δt"),
        comp.not_evaluated("repeatability", "repeatability between records", _REPEAT_REASON,
                           "deg"),
    )

    def model(ops: Ops, x: Mapping[str, Any]) -> Any:
        reference = x["encoder_accuracy"] + x["motion_distortion"]
        return (phase + (x["noise"] + reference) * (180.0 / math.pi)
                - 360.0 * f_hz * (x["sync"] + x["timing"]) + x["repeatability"])

    return Measurand(f"FRF phase at {f_hz:.4f} Hz", "deg", model, inputs,
                     _point_definition("phase", point, channel, at))


def _channel_of(sensor: str, results: RunResults) -> str:
    """Map a misalignment sensor label (SZ) to its channel (v_sz) when that channel exists."""
    channel = f"v_{sensor.lower()}"
    known = [s.channel for s in results.metadata.sensors]
    return channel if channel in known or not known else known[0]


def _misalignment_steps(results: RunResults, c: RigConstants) -> tuple[float, float]:
    """Peak excitation (°/s², docs/method.md §4.5: 100) and record length of the scenario steps."""
    sine = [s for s in results.steps_of_kind("sine") if s.mounting.scenario]
    accel = max(finite_values(s.accel_dps2 for s in sine) or [100.0])
    return accel, float(min([s.samples for s in sine] or [c.record_samples]))


def _delta_e_deg(results: RunResults, set_label: str, sensor: str) -> float | None:
    """δ_e of one sensor in one set; a set or sensor the scenario needs and lacks is an error."""
    block = results.analysis.misalignment
    entry = block.sets.get(set_label, {}).get(sensor) if block else None
    if entry is None:
        raise ResultsContractError(f"results.json: analysis.misalignment.sets.{set_label}: "
                                   f"no sensor {sensor!r} (scenario needs it)")
    return finite(entry.delta_e_deg)


def misalignment_measurand(results: RunResults, scenario: str, sensor: str,
                           c: RigConstants) -> Measurand | None:
    """δ = (arcsin(sin δ̂_e + n_o) − arcsin(sin δ̂_ep + n_p))·90/π + (w_o − w_p)/2  [deg]."""
    block = results.analysis.misalignment
    if block is None or not block.sets:
        return None
    original, pivoted = SCENARIO_SETS[scenario]
    de_o = _delta_e_deg(results, original, sensor)
    de_p = _delta_e_deg(results, pivoted, sensor)
    if de_o is None or de_p is None:
        return None
    channel = _channel_of(sensor, results)
    noise_v, source = comp.noise_rms_v(results, channel)
    k_v = results.sensor(channel).nominal_scale_v_per_dps2
    accel_dps2, samples = _misalignment_steps(results, c)
    rel = noise_v * math.sqrt(2.0 / samples) / (k_v * accel_dps2)
    wobble_deg = c.wobble_arcsec / 3600.0
    note = f"σ·√(2/N)/|A_z|, {noise_v * 1e3:.2f} mV ({source})"
    inputs = (
        Input("noise_o", "sensor noise, original mounting", 0.0, rel, "normal", "1", note),
        Input("noise_p", "sensor noise, pivoted mounting", 0.0, rel, "normal", "1", note),
        Input("wobble_o", "wobble, original mounting", 0.0, wobble_deg, "rectangular", "deg",
              f"≤ {c.wobble_arcsec:g}″"),
        Input("wobble_p", "wobble, pivoted mounting", 0.0, wobble_deg, "rectangular", "deg",
              f"≤ {c.wobble_arcsec:g}″"),
        Input("orthogonality", "table orthogonality", 0.0, c.orthogonality_arcsec / 3600.0,
              "rectangular", "deg", "common to both mountings: cancels in the pivot difference"),
    )
    s_o, s_p = math.sin(math.radians(de_o)), math.sin(math.radians(de_p))

    def model(ops: Ops, x: Mapping[str, Any]) -> Any:
        d_o = ops.asin(s_o + x["noise_o"]) * (180.0 / math.pi) + x["wobble_o"]
        d_p = ops.asin(s_p + x["noise_p"]) * (180.0 / math.pi) + x["wobble_p"]
        return (d_o - d_p) / 2.0 + 0.0 * x["orthogonality"]

    return Measurand(f"misalignment {sensor} scenario {scenario}", "deg", model, inputs)


def sensor_tilt_measurand(results: RunResults, scenario: str, channel: str,
                          c: RigConstants) -> Measurand | None:
    """θ = √((t_x + r_x)² + (t_y + r_y)²) + (w_o − w_p)/2  [deg]: the sensor's own axis tilt.

    The pivot-separated part of the sensitivity-matrix estimate (half the original − pivoted
    difference of the row's direction ratios): what flips with the pivot is the sensor's, the
    mounting's part cancels. ``r_x``/``r_y`` are the repetitions' scatter of the two tilts
    (type A, the repetitions re-mount what the scenario re-mounts); wobble differs between
    the two mountings and enters the half-difference by halves; orthogonality is common to both.
    """
    block = results.analysis.misalignment
    matrix = block.matrix if block is not None else None
    entry = matrix.scenarios.get(scenario, {}).get(channel) if matrix is not None else None
    if entry is None:
        return None
    t_x, t_y = finite(entry.sensor_tilt_x_deg), finite(entry.sensor_tilt_y_deg)
    if t_x is None or t_y is None:
        return None
    u_x, u_y = (finite(u) or 0.0 for u in entry.u_sensor_tilt_deg)
    dof = max(entry.repetitions - 1, 1)
    wobble_deg = c.wobble_arcsec / 3600.0
    scatter = f"scatter of {entry.repetitions} repetitions (standard error of the mean)"
    labels = ("repeatability, tilt towards the sensor's x",
              "repeatability, tilt towards the sensor's y")
    repeat = (
        Input("repeat_x", labels[0], 0.0, u_x, "normal", "deg", scatter, kind="A", dof=dof),
        Input("repeat_y", labels[1], 0.0, u_y, "normal", "deg", scatter, kind="A", dof=dof),
    ) if entry.repetitions > 1 else tuple(
        comp.not_evaluated(name, label, "one repetition: no scatter to evaluate", "deg")
        for name, label in zip(("repeat_x", "repeat_y"), labels, strict=True))
    inputs = (
        *repeat,
        Input("wobble_o", "wobble, original mounting", 0.0, wobble_deg, "rectangular", "deg",
              f"≤ {c.wobble_arcsec:g}″"),
        Input("wobble_p", "wobble, pivoted mounting", 0.0, wobble_deg, "rectangular", "deg",
              f"≤ {c.wobble_arcsec:g}″"),
    )

    def model(ops: Ops, x: Mapping[str, Any]) -> Any:
        tilt = ops.sqrt((t_x + x["repeat_x"]) ** 2 + (t_y + x["repeat_y"]) ** 2)
        return tilt + (x["wobble_o"] - x["wobble_p"]) / 2.0

    return Measurand(f"sensor axis tilt {channel} scenario {scenario}", "deg", model, inputs)
