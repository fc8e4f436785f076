"""Budget rows every calibration shares (ISO 16063-15/-21 component lists), each with its basis.

Each function returns the :class:`~aatest.metrology.uncertainty.gum.Input` of one component —
reference (encoder accuracy and resolution, reference method, motion distortion), transverse
motion, mounting misalignment, the logger (offset, gain, resolution), temperature,
repeatability — quantified from the recording when it shows it (:mod:`.evidence`), else from
the rig description (:class:`~aatest.engine.rig_description.Instruments`), else
returned as a *not evaluated* row (zero contribution, the reason in the basis). Relative
inputs are dimensionless (unit ``1``); the measurement models multiply the estimate by
``(1 + x)``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Literal

from aatest.engine.datasheet import SensorDatasheet
from aatest.metrology.uncertainty.gum import Distribution, Input
from aatest.metrology.uncertainty.rig_constants import RigConstants
from aatest.metrology.uncertainty.statistics import PAIR, finite
from aatest.results import RunResults
from aatest.results.quantities import reference_name

#: one arcsecond in radians
ARCSEC_RAD = math.pi / (180.0 * 3600.0)
#: cross-axis sensitivity a sensor datasheet states when the sensor record carries none
TYPICAL_CROSS_AXIS = SensorDatasheet(model="reference").cross_axis_limit


def rel(name: str, label: str, spread: float, note: str, dist: Distribution = "normal",
        kind: Literal["A", "B"] = "B") -> Input:
    """A relative (dimensionless) input: ``spread`` is u (normal) or the half-width."""
    return Input(name, label, 0.0, abs(spread), dist, "1", note, kind)


def not_evaluated(name: str, label: str, reason: str, unit: str = "1") -> Input:
    """A component that exists but cannot be quantified here: zero, with its reason."""
    return Input(name, label, 0.0, 0.0, "normal", unit, f"not evaluated: {reason}",
                 evaluated=False)


# --- reference --------------------------------------------------------------------------------

def encoder_accuracy(c: RigConstants, amplitude_arcsec: float) -> Input:
    """Encoder accuracy a over the motion amplitude A (arcsec; a dimensionless, rectangular,
    relative half-width).

    Over a motion of amplitude A the error can change by at most 2A times its slope, and its
    slope is bounded by a·2π·n (n: the error's highest spatial frequency, cycles/rev); and by
    no more than a itself: the half-width is min(a/A, a·2π·n/rev).
    """
    enc = c.instruments.encoder
    a_rad = enc.accuracy_arcsec * ARCSEC_RAD
    slope = a_rad * enc.error_cycles_per_rev
    over_amplitude = enc.accuracy_arcsec / amplitude_arcsec
    bound = min(slope, over_amplitude)
    how = (f"over A = {amplitude_arcsec:.1f}″" if over_amplitude <= slope else
           f"slope bound a·2π·{enc.error_cycles_per_rev}/rev (A = {amplitude_arcsec:.1f}″)")
    what = f"encoder accuracy ±{enc.accuracy_arcsec:g}″"
    note = c.encoder_note("accuracy_arcsec", what, enc.cert_text())
    return rel("encoder_accuracy", "reference: encoder accuracy", bound, f"{note} {how}",
               "rectangular")


def encoder_resolution(c: RigConstants, amplitude_arcsec: float) -> Input:
    """One encoder count q over the amplitude A (arcsec): u = q/√12 / A, dimensionless."""
    enc = c.instruments.encoder
    q = enc.resolution_arcsec
    what = f"encoder resolution {enc.resolution_counts_per_rev} counts/rev (q = {q:.3g}″)"
    return rel("encoder_resolution", "reference: encoder resolution",
               q / math.sqrt(12.0) / amplitude_arcsec,
               f"{c.encoder_note('resolution_counts_per_rev', what)}, u = q/√12 over "
               f"A = {amplitude_arcsec:.1f}″")


def reference_method(results: RunResults, steps: Sequence[str], chosen: str) -> Input:
    """Error of the chosen reference method, estimated as the largest gain difference at the
    fundamental between it and the other reference methods on the same records (rectangular).

    Needs the ``reference`` analysis (its per-step gains of every method against the same
    baseline); without it the component is not evaluated.
    """
    compared = results.analysis.reference.root if results.analysis.reference else {}
    gains: dict[str, list[float]] = {}
    for step in steps:
        for method, row in compared.get(step, {}).items():
            gain = finite(row.gain)
            if gain is not None:
                gains.setdefault(method, []).append(gain)
    if len(gains) < PAIR:
        return not_evaluated("reference_method", "reference: method error",
                             "no reference analysis comparing methods in this run")
    mean = {m: sum(v) / len(v) for m, v in gains.items()}
    baseline = next((mean[m] for m in (chosen, *_ALIASES.get(chosen, ())) if m in mean),
                    sum(mean.values()) / len(mean))
    worst_method, worst = max(((m, abs(g / baseline - 1.0)) for m, g in mean.items()),
                              key=lambda item: item[1])
    return rel("reference_method", f"reference: method error ({reference_name(chosen)})",
               worst, f"measured: largest gain difference of the {len(mean)} reference methods "
               f"at the fundamental, {worst * 100:.4f} % ({reference_name(worst_method)} vs "
               f"{reference_name(chosen)})", "rectangular")


#: public reference names → the names the reference analysis reports them under
_ALIASES: dict[str, tuple[str, ...]] = {
    "smoothed": ("smooth",), "table_estimate": ("table",), "fit": ("savgol",),
    "sliding_mode": ("levant",), "central": ("central_rate", "central_position"),
    "five_point": ("five_point_rate", "five_point_position")}


def motion_distortion(c: RigConstants, steps: Sequence[str]) -> list[Input]:
    """Servo distortion of the table motion, measured from the position log.

    Harmonics in the motion reach the straight-line slope only weighted by their power
    (THD²) times the sensor's gain difference between harmonic and fundamental (≤ 1):
    half-width THD² (rectangular). The non-commanded content at the fundamental (tracking
    error) is measured and stated; the reference is the measured motion, so it is not an error
    of the ratio (zero contribution).
    """
    found = [c.evidence.motion[s] for s in steps if s in c.evidence.motion]
    if not found:
        reason = "no position log of a coherent sine record available" if not \
            c.evidence.recording else "the records are not coherent sines"
        return [not_evaluated("motion_distortion", "reference: motion distortion (THD)", reason)]
    thd = max(m.thd_accel for m in found)
    tracking = max(m.tracking_rel for m in found)
    return [
        rel("motion_distortion", "reference: motion distortion (THD)", thd**2,
            f"measured: THD of the table acceleration {thd * 100:.3f} % (position log, "
            f"harmonics 2–5); enters as THD²", "rectangular"),
        rel("tracking", "reference: servo tracking (non-commanded content at f)", 0.0,
            f"measured: fundamental {tracking * 100:.3f} % off the command; the reference is "
            "the measured motion, so it does not enter the ratio"),
    ]


# --- transverse motion and mounting ---------------------------------------------------------

def axis_tilt_rad(c: RigConstants) -> float:
    """Combined wobble and orthogonality bound of the rotation axis, rad."""
    return math.hypot(c.wobble_arcsec, c.orthogonality_arcsec) * ARCSEC_RAD


def wobble(c: RigConstants) -> Input:
    """cos ε − 1 of the axis tilt: the sensitive axis sees α·cos ε."""
    geo = c.instruments.table
    what = f"wobble ≤ {geo.wobble_arcsec:g}″, orthogonality ≤ {geo.orthogonality_arcsec:g}″"
    return Input("wobble", "transverse motion: axis tilt (cosine)", 0.0, axis_tilt_rad(c),
                 "cosine_error", "1", c.source(what) + ", cos ε − 1")


def transverse(c: RigConstants, channel: str) -> Input:
    """Transverse acceleration α·sin ε of a tilted axis times the cross-axis sensitivity
    (the datasheet's typical limit: the sensor record states none)."""
    ratio = TYPICAL_CROSS_AXIS
    tilt = axis_tilt_rad(c)
    return rel("transverse", "transverse motion × cross-axis sensitivity",
               ratio * math.sin(tilt),
               f"{c.source('wobble/orthogonality')} ε ≤ {tilt / ARCSEC_RAD:.2f}″ × cross-axis "
               f"{ratio * 100:g} % (typical datasheet limit 1 % (not stated))", "rectangular")


def _misalignment_result_deg(results: RunResults, channel: str) -> float | None:
    """Largest |misalignment| + U measured for this sensor in this run, degrees, or None."""
    sensor = channel.removeprefix("v_").upper()
    block = results.analysis.misalignment
    angles = []
    for sensors in (block.scenarios.values() if block else ()):
        entry = sensors.get(sensor)
        value = finite(entry.delta_deg) if entry is not None else None
        if entry is not None and value is not None:
            angles.append(abs(value) + (finite(entry.expanded_uncertainty) or 0.0))
    return max(angles) if angles else None


def mounting(c: RigConstants, results: RunResults, channel: str,
             name: str = "mounting") -> Input:
    """Cosine error of the mounting misalignment: measured in this run, else the stated bound."""
    measured = _misalignment_result_deg(results, channel)
    if measured is not None:
        bound, basis = measured, f"measured: misalignment result of this run, ≤ {measured:.3f}°"
    else:
        bound = c.instruments.mounting_accuracy_deg
        basis = c.source(f"mounting accuracy ±{bound:g}°")
    return Input(name, "mounting misalignment (cosine)", 0.0, math.radians(bound),
                 "cosine_error", "1", basis + ", cos δ − 1")


# --- the sensor logger -------------------------------------------------------------------------

def logger_gain(c: RigConstants) -> Input:
    """Logger gain accuracy, relative half-width (rectangular)."""
    lg = c.instruments.logger
    return rel("logger_gain", "logger gain accuracy", lg.gain_accuracy_pct / 100.0,
               c.source(f"logger gain accuracy {lg.gain_accuracy_pct:g} %", lg.cert_text()),
               "rectangular")


def logger_offset(c: RigConstants) -> Input:
    """Logger offset accuracy, volts, half-width (rectangular): u = a/√3."""
    lg = c.instruments.logger
    return Input("logger_offset", "logger offset accuracy", 0.0, lg.offset_accuracy_v,
                 "rectangular", "V",
                 c.source(f"logger offset accuracy ±{lg.offset_accuracy_v * 1e3:g} mV",
                          lg.cert_text()))


def logger_resolution_v(c: RigConstants, scale: float = 1.0) -> Input:
    """One converter step q: u = q/√12 (16 bit over ±10 V: q = 305 µV, u = 88 µV).

    ``scale`` converts volts into the unit of the quantity (e.g. √2/2 for a half-difference).
    """
    lg = c.instruments.logger
    what = f"logger resolution {lg.bits} bit over {lg.range_v[0]:g}…{lg.range_v[1]:g} V " \
           f"(q = {lg.step_v * 1e6:.0f} µV), u = q/√12"
    return Input("logger_resolution", "logger resolution", 0.0, lg.resolution_u_v * scale,
                 "normal", "V", c.source(what))


# --- the sensor ------------------------------------------------------------------------------

def noise_rms_v(results: RunResults, channel: str) -> tuple[float, str]:
    """Sensor output noise (V RMS) and where it came from: measured, else the sensor record."""
    noise = results.analysis.noise.get(channel) if results.analysis.noise else None
    measured = finite(noise.rms_v) if noise is not None else None
    if measured is not None:
        return measured, "measured (noise analysis)"
    recorded = any(s.channel == channel for s in results.metadata.sensors)
    return (results.sensor(channel).noise_rms_v,
            "sensor datasheet" if recorded else "datasheet limit of the reference sensor")


# --- temperature and repeatability ---------------------------------------------------------

def temperature(c: RigConstants, steps: Sequence[str] | None, coefficient: float,
                coefficient_note: str, unit: str) -> tuple[Input, str]:
    """Temperature component and the temperature (°C) the measurand is stated at.

    ``coefficient`` is the temperature coefficient in the quantity's unit per °C (e.g. 1/°C
    for a relative input, V/°C for the bias).

    Logged: the measurand is at the mean logged temperature, known to the thermometer's
    accuracy and the spread during the records; u = |TC|·√(u_T² + s_T²). Not logged: the
    measurand is at the reference temperature and the lab's stated tolerance about it is a
    rectangular half-width |TC|·ΔT.
    """
    logged = c.evidence.temperature_over(list(steps) if steps is not None else None)
    thermo = c.instruments.thermometer
    if logged is not None:
        u_t = math.hypot(thermo.accuracy_c / math.sqrt(3.0), logged.std_c)
        thermometer = c.source(f"thermometer ±{thermo.accuracy_c:g} °C", thermo.cert_text())
        note = (f"measured: logged temperature {logged.mean_c:.2f} °C (s = {logged.std_c:.3f} °C)"
                f"; {thermometer}; × {coefficient_note}")
        return (Input("temperature", "temperature during the record", 0.0,
                      abs(coefficient) * u_t, "normal", unit, note),
                f"{logged.mean_c:.1f} °C (logged)")
    lab = c.instruments.lab
    stated = f"lab {lab.reference_temperature_c:g} ± {lab.temperature_tolerance_c:g} °C"
    note = f"not logged: {c.source(stated)} × {coefficient_note}"
    return (Input("temperature", "lab temperature vs reference temperature", 0.0,
                  abs(coefficient) * lab.temperature_tolerance_c, "rectangular", unit, note),
            f"{lab.reference_temperature_c:g} °C (reference temperature; not logged)")
