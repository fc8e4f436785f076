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
from typing import Any

from aatest.engine.datasheet import REFERENCE_SCALE_V_PER_DPS2
from aatest.engine.uncertainty import access as ex
from aatest.engine.uncertainty.gum import Input, Measurand, Ops
from aatest.engine.uncertainty.measurands import ARCSEC_RAD, RigConstants

#: misalignment scenario → (original, pivoted) set labels (docs/interfaces.md §5)
SCENARIO_SETS: dict[str, tuple[str, str]] = {"1": ("A", "B"), "2": ("C", "D"), "3": ("E", "F"),
                                             "4": ("G", "H")}


def _record_samples(point: Mapping[str, Any], results: Mapping[str, Any], c: RigConstants) -> float:
    samples = ex.as_float(point.get("samples"))
    if samples:
        return samples
    sine = ex.step_values(ex.steps_of_kind(results, "sine"), "samples")
    return float(max(sine)) if sine else float(c.record_samples)


def _bin_noise(point: Mapping[str, Any], results: Mapping[str, Any], c: RigConstants,
               u_key: str, to_relative: float) -> tuple[float, str]:
    """Relative (gain) or radian (phase) standard uncertainty of the bin ratio Y/X, and its basis.

    The FRF analysis' own ``u_gain_db``/``u_phase_deg`` are used when stated; otherwise white
    noise at the bin of both the sensor output (``snr_db``) and the table reference
    (``table_snr_db``), each 1/√(N·SNR).
    """
    stated = ex.as_float(point.get(u_key))
    if stated is not None:
        return stated * to_relative, f"u from the FRF analysis ({u_key})"
    n = _record_samples(point, results, c)
    parts = {k: ex.as_float(point.get(k)) for k in ("snr_db", "table_snr_db")}
    rel2 = sum(1.0 / (n * 10.0 ** (db / 10.0)) for db in parts.values() if db is not None)
    shown = ", ".join(f"{k} {v:.1f}" for k, v in parts.items() if v is not None) or "no SNR"
    return math.sqrt(rel2), f"1/√(N·SNR) of output and reference ({shown})"


def frf_gain_measurand(point: Mapping[str, Any], results: Mapping[str, Any],
                       c: RigConstants) -> Measurand | None:
    """G = Ĝ + 20·log10((1 + e_out) / ((1 + e_pos)·(1 + e_tilt)))  [dB]."""
    gain = ex.require_float(point, "gain_db", "analysis.frf point")
    f_hz = ex.require_float(point, "frequency_hz", "analysis.frf point")
    accel = ex.require_float(point, "accel_dps2", "analysis.frf point")
    if gain is None or not f_hz or not accel:
        return None
    amp_arcsec = abs(accel) / (2 * math.pi * f_hz) ** 2 * 3600.0
    noise, basis = _bin_noise(point, results, c, "u_gain_db", math.log(10.0) / 20.0)
    inputs = (
        Input("noise", "sensor and reference noise (at the bin)", 0.0, noise, "normal", "1",
              basis),
        Input("position", "table position accuracy", 0.0, c.position_accuracy_arcsec / amp_arcsec,
              "rectangular", "1",
              f"{c.position_accuracy_arcsec:g}″ over A = {amp_arcsec:.1f}″"),
        Input("tilt", "wobble / orthogonality (axis tilt)", 0.0,
              math.hypot(c.wobble_arcsec, c.orthogonality_arcsec) * ARCSEC_RAD, "cosine_error",
              "1", "cos ε − 1"),
    )

    def model(ops: Ops, x: Mapping[str, Any]) -> Any:
        reference = (1.0 + x["position"]) * (1.0 + x["tilt"])
        return gain + 20.0 * ops.log10((1.0 + x["noise"]) / reference)

    return Measurand(f"FRF gain at {f_hz:.4f} Hz", "dB", model, inputs)


def frf_phase_measurand(point: Mapping[str, Any], results: Mapping[str, Any],
                        c: RigConstants) -> Measurand | None:
    """φ = φ̂ + e_out·180/π − 360·f·δt  [deg]."""
    phase = ex.require_float(point, "phase_deg", "analysis.frf point")
    f_hz = ex.require_float(point, "frequency_hz", "analysis.frf point")
    if phase is None or not f_hz:
        return None
    sync = ex.analysis(results, "sync") or {}
    residual_us = ex.as_float(sync.get("residual_rms_us")) or 3.5
    noise, basis = _bin_noise(point, results, c, "u_phase_deg", math.pi / 180.0)
    inputs = (
        Input("noise", "sensor and reference noise (at the bin)", 0.0, noise, "normal", "rad",
              basis),
        Input("sync", "sync residual (logger alignment)", 0.0, residual_us * 1e-6, "normal", "s",
              f"{residual_us:g} µs RMS clock-relation residual"),
    )

    def model(ops: Ops, x: Mapping[str, Any]) -> Any:
        return phase + x["noise"] * (180.0 / math.pi) - 360.0 * f_hz * x["sync"]

    return Measurand(f"FRF phase at {f_hz:.4f} Hz", "deg", model, inputs)


def _channel_of(sensor: str, results: Mapping[str, Any]) -> str:
    """Map a misalignment sensor label (SZ) to its channel (v_sz) when that channel exists."""
    channel = f"v_{sensor.lower()}"
    known = ex.sensors(results)
    return channel if channel in known or not known else next(iter(known))


def _misalignment_steps(results: Mapping[str, Any], c: RigConstants) -> tuple[float, float]:
    """Peak excitation (°/s², docs/method.md §4.5: 100) and record length of the scenario steps."""
    sine = [s for s in ex.steps_of_kind(results, "sine")
            if isinstance(s.get("mounting"), Mapping) and s["mounting"].get("scenario")]
    accel = max(ex.step_values(sine, "accel_dps2") or [100.0])
    return accel, min(ex.step_values(sine, "samples") or [float(c.record_samples)])


def misalignment_measurand(results: Mapping[str, Any], scenario: str, sensor: str,
                           c: RigConstants) -> Measurand | None:
    """δ = (arcsin(sin δ̂_e + n_o) − arcsin(sin δ̂_ep + n_p))·90/π + (w_o − w_p)/2  [deg]."""
    sets = ex.misalignment_sets(results)
    if not sets:
        return None
    original, pivoted = SCENARIO_SETS[scenario]
    de_o = ex.require_float(ex.require(sets, original, "analysis.misalignment.sets").get(sensor),
                            "delta_e_deg", f"analysis.misalignment.sets.{original}.{sensor}")
    de_p = ex.require_float(ex.require(sets, pivoted, "analysis.misalignment.sets").get(sensor),
                            "delta_e_deg", f"analysis.misalignment.sets.{pivoted}.{sensor}")
    if de_o is None or de_p is None:
        return None
    channel = _channel_of(sensor, results)
    noise_v, source = ex.noise_rms_v(results, channel)
    info = ex.sensors(results).get(channel, {})
    k_v = ex.as_float(info.get("nominal_scale_v_per_dps2")) or REFERENCE_SCALE_V_PER_DPS2
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
