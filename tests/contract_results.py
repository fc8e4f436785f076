"""A hand-made ``results.json`` with realistic numbers (docs/method.md §1.3, §4), valid for the
typed record (:class:`aatest.results.RunResults`).

Shared by the report and uncertainty tests (``from contract_results import make_results``;
``typed_results()`` is the same document as the typed record). Values an analysis would state
but these tests want absent are ``None`` (read back as NaN, i.e. "not estimated").

Three-sensor unit (v_sz on I, v_sy on O, v_sx on P); FRF points follow a 60 Hz, ζ = 0.7
second-order sensor with a 13.5 ms transport delay at −47.9 dB (K = 4.014 mV/(°/s²)).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy import signal

from aatest.engine.interfaces import SensorDatasheet
from aatest.engine.procedure.models import Acceptance
from aatest.metrology.uncertainty import apply_uncertainty
from aatest.metrology.verdicts import apply_verdicts
from aatest.results import RunResults

K_V_PER_DPS2 = 0.004014
CHANNELS = {"v_sz": ("I", "SZ", "A1234-Z"), "v_sy": ("O", "SY", "A1234-Y"),
            "v_sx": ("P", "SX", "A1234-X")}
FRF_HZ = (0.396728516, 0.991821289, 1.998901367, 3.997802734, 5.996704102, 7.995605469,
          9.994506836)


def _frf_points(delay_s: float = 0.0135) -> list[dict[str, Any]]:
    points = []
    for f in FRF_HZ:
        s = 2j * math.pi * f
        wn = 2 * math.pi * 60.0
        h = K_V_PER_DPS2 * wn**2 / (s**2 + 2 * 0.7 * wn * s + wn**2) * np.exp(-s * delay_s)
        delay = float(-np.angle(h) / (2 * math.pi * f))
        points.append({
            "frequency_hz": f, "accel_dps2": 100.0, "gain_db": 20 * math.log10(abs(h)),
            "phase_deg": math.degrees(np.angle(h)), "delay_s": delay,
            "delay_samples": delay * 2000.0, "thd": 0.002 + 0.0004 * f, "snr_db": 49.0 - 0.1 * f,
            "snr6_db": 48.0 - 0.1 * f, "table_thd": None, "table_snr_db": None,
            "table_snr6_db": None, "measured_accel_dps2": 100.0, "gain_v_per_dps2": abs(h),
            "re": h.real, "im": h.imag, "u_gain_db": None, "u_phase_deg": None,
            "u_delay_s": None, "coherent": True, "group": "accel-100",
            "step": f"sw-{f:.4f}Hz", "sample_rate_hz": 2000.0,
        })
    return points


def _transfer_function(delay_s: float = 0.0135, dt: float = 0.0005) -> dict[str, Any]:
    """The FRF's sensor model, discretised (ZOH) at 2 kHz, with a separate delay term."""
    wn = 2 * math.pi * 60.0
    num, den, _ = signal.cont2discrete(([K_V_PER_DPS2 * wn**2], [1, 2 * 0.7 * wn, wn**2]), dt)
    num, den = np.ravel(num), np.ravel(den)
    poles = [[p.real, p.imag] for p in np.roots(den)]
    model = {"poles": poles,
             "zeros": [[z.real, z.imag] for z in np.roots(np.trim_zeros(num, "f"))],
             "delay_s": delay_s, "fit_pct": 98.4, "nAIC": -14.2, "FPE": 6.1e-7,
             "num": num.tolist(), "den": den.tolist(), "dt": dt, "n": 2, "m": 1,
             "delay_samples": 27, "delay_source": "xcorr", "fit_id_pct": 98.6,
             "zeros_outside_unit_circle": 0,
             "xcorr": {"delay_samples": 27, "delay_s": delay_s, "strength": 0.9,
                       "accepted": True},
             "continuous": {"num": [K_V_PER_DPS2 * wn**2], "den": [1, 2 * 0.7 * wn, wn**2],
                            "poles_rad_s": [[-0.7 * wn, wn * 0.714], [-0.7 * wn, -wn * 0.714]],
                            "natural_frequencies_hz": [60.0, 60.0], "damping": [0.7, 0.7],
                            "delay_s": delay_s, "dc_gain": K_V_PER_DPS2},
             "candidates": [],
             "second_order_delay": {"gain_v_per_dps2": K_V_PER_DPS2, "natural_frequency_hz": 60.0,
                                    "damping": 0.7, "delay_s": delay_s,
                                    "u_natural_frequency_hz": 0.4, "u_damping": 0.01,
                                    "u_delay_s": 1e-5, "fit_pct": 98.1}}
    return {**model, "group": "accel-100", "groups": {"accel-100": model}}


def _steps() -> list[dict[str, Any]]:
    steps: list[dict[str, Any]] = []
    for rep in (1, 2, 3):
        for outer in (0.0, 180.0):
            steps.append({"id": f"st-o{outer:g}-r{rep}", "kind": "static", "axis": "none",
                          "duration_s": 67.5, "samples": 135000, "outer_deg": outer,
                          "repetition": rep, "status": "recorded"})
    steps.append({"id": "sf-1hz", "kind": "sine", "axis": "inner", "duration_s": 65.536,
                  "samples": 131072, "frequency_hz": 1.007080078, "accel_dps2": 400.0,
                  "amplitude_deg": 400.0 / (2 * math.pi * 1.007080078) ** 2, "status": "recorded"})
    for t in (22.0, -21.0, 48.0):
        steps.append({"id": f"ch-{t:g}", "kind": "chamber", "temperature_c": t, "soak_s": 900.0})
    return steps


def _misalignment() -> dict[str, Any]:
    rng = np.random.default_rng(7)
    sets: dict[str, Any] = {}
    for i, label in enumerate("ABCDEFGH"):
        pivoted = i % 2 == 1
        sets[label] = {}
        for sensor, true_deg in (("SZ", 0.21), ("SY", -0.12), ("SX", 0.34)):
            mount = 0.45 + 0.05 * rng.standard_normal()  # mounting error > |δ|
            de = abs(mount + (-true_deg if pivoted else true_deg))
            phase = 0.15 * rng.standard_normal()  # cross response nearly in phase
            sets[label][sensor] = {
                "cross_ratio_x": abs(math.sin(math.radians(de))) * 0.8,
                "cross_ratio_y": abs(math.sin(math.radians(de))) * 0.6,
                "delta_A": [0.4 * math.sin(math.radians(de)) * math.cos(phase),
                            0.4 * math.sin(math.radians(de)) * math.sin(phase)], "delta_e_deg": de,
                "A_z": [0.4, 0.0],
            }
    scenarios = {
        str(n): {s: {"delta_deg": (sets[o][s]["delta_e_deg"] - sets[p][s]["delta_e_deg"]) / 2,
                     "A_S": [0.4, 0.0]}
                 for s in ("SZ", "SY", "SX")}
        for n, (o, p) in zip("1234", ("AB", "CD", "EF", "GH"), strict=True)
    }
    return {"sets": sets, "scenarios": scenarios}


def _temperature_columns() -> dict[str, list[Any]]:
    temps = (22, 7.5, -2, -11, -21, -14, -5, 4, 20, 29, 38, 48, 38, 29, 22)
    rng = np.random.default_rng(3)
    columns: dict[str, list[Any]] = {"temperatures_c": [], "branch": [], "bias_v": [],
                                     "scale_temperatures_c": [], "scale_v_per_dps2": []}
    for i, t in enumerate(temps):
        branch = "cooling" if i < 5 else "heating" if i < 12 else "return"
        bias = 2.4987 - 0.00031 * (t - 25) + (0.0002 if branch == "cooling" else 0.0)
        scale = K_V_PER_DPS2 * (1 + 0.00021 * (t - 25))
        columns["temperatures_c"].append(float(t))
        columns["scale_temperatures_c"].append(float(t))
        columns["branch"].append(branch)
        columns["bias_v"].append(bias + 2e-5 * rng.standard_normal())
        columns["scale_v_per_dps2"].append(scale * (1 + 2e-5 * rng.standard_normal()))
    return columns


def _mounting(bias_v: float, g: float, u_v: float, u_g: float) -> dict[str, Any]:
    return {"bias_v": bias_v, "bias_u_v": u_v, "g_sensitivity_dps2_per_g": g,
            "g_sensitivity_u_dps2_per_g": u_g, "repetitions": 3,
            "line": {"bias_v": bias_v, "g_slope_v_per_g": g * K_V_PER_DPS2,
                     "residual_rms_v": 2e-5}}


def _scale_factor(a1: float, b: float) -> dict[str, Any]:
    ci95 = [[-0.40, -0.24], [a1 - 0.069, a1 + 0.069]]
    return {"scale_v_per_dps2": 1 / a1, "scale_u_v_per_dps2": None, "scale_ci95": [None, None],
            "offset_v": b, "offset_u_v": 1e-5, "order": 1, "rmse_dps2": 14.5,
            "coefficients": [-0.32, a1], "ci95": ci95,
            "fit": {"order": 1, "coefficients": [-0.32, a1], "std_uncertainty": [0.04, 0.035],
                    "ci95": ci95, "covariance": [], "correlation": [], "sse": 1.0,
                    "rmse": 14.5, "r2": 0.997, "n": 131072},
            "volts_mean_v": b, "validation": {"rmse_dps2": [14.6, 14.5], "naic": [5.4, 5.3]},
            "nonlinearity_dps2": 0.11,
            "inverse": {"order": 1, "coefficients_v": [b, 1 / a1], "ci95": [], "rmse_v": 6e-5},
            "reference": "smooth", "alignment_delay_s": 0.0, "steps": ["sf-1hz"],
            "scale_deviation_pct": 100 * (1 / (a1 * K_V_PER_DPS2) - 1),
            "nonlinearity_pct_fr": 0.011}


def _noise(rms_v: float) -> dict[str, Any]:
    return {"rms_v": rms_v, "rms_max_v": rms_v, "rms_per_step_v": [rms_v],
            "rms_dps2": rms_v / K_V_PER_DPS2, "band_hz": 100.0,
            "psd_floor_v_per_sqrt_hz": rms_v / 10.0,
            "allan_dps2": {"tau_s": [0.1, 1.0], "adev": [0.08, 0.025]},
            "record_step": "st-o0-r1"}


def _analysis() -> dict[str, Any]:
    bias, scale, temperature, noise, frf, tf = {}, {}, {}, {}, {}, {}
    for n, ch in enumerate(CHANNELS):
        b = 2.4987 + 0.0011 * n
        g_sens = 0.21 - 0.05 * n
        bias[ch] = {"bias_v": b, "g_sensitivity_dps2_per_g": g_sens,
                    "mountings": {"original": _mounting(b - 1.2e-5, g_sens + 0.002, 7e-6, 1.1e-3),
                                  "pivoted": _mounting(b + 1.2e-5, g_sens - 0.002, 7e-6, 1.1e-3)}}
        a1 = 1.0 / (K_V_PER_DPS2 * (1 - 0.0009 * n))
        scale[ch] = _scale_factor(a1, b)
        temperature[ch] = {"bias_coefficient_v_per_c": -0.00031,
                           "scale_coefficient_per_c": 0.00021,
                           "hysteresis_v": 0.0002, **_temperature_columns()}
        noise[ch] = _noise(0.00101)
        frf[ch] = _frf_points()
        tf[ch] = _transfer_function()
    return {"sync": {"drift_ppm": 12.3, "offset_s": 0.3521, "residual_rms_us": 2.9,
                     "edges_used": 6553},
            "bias": bias, "scale_factor": scale, "frf": frf, "transfer_function": tf,
            "temperature": temperature, "misalignment": _misalignment(), "noise": noise}


_SVG = ('<svg xmlns="http://www.w3.org/2000/svg" width="120" height="40" viewBox="0 0 120 40">'
        '<rect x="1" y="1" width="118" height="38" fill="#eef"/>'
        '<text x="8" y="25">PSD</text></svg>')


def make_results() -> dict[str, Any]:
    sensors = [{"channel": ch, "axis": ax, "model": "sr207-aamu", "serial": serial,
                "nominal_bias_v": 2.5, "nominal_scale_v_per_dps2": K_V_PER_DPS2,
                "range_dps2": 572.958, "noise_rms_v": 0.003, "bias_tolerance_v": 0.01,
                "scale_tolerance_pct": 1.0}
               for ch, (ax, _, serial) in CHANNELS.items()]
    return {
        "procedure": "full-calibration",
        "rig": {"turntable": "sim", "daq": "sim", "chamber": "sim"},
        "steps": _steps(), "analysis": _analysis(), "analysis_errors": {}, "analysis_skipped": [],
        "lab_duration_s": 86400.0, "wall_duration_s": 312.4,
        "metadata": {
            "procedure_sha256": "3f" * 32, "procedure_text": "procedure: full-calibration\n"
            "steps:\n  - static: {positions: [up, down]}\n", "rig": {"turntable": "sim"},
            "plugins": {"turntable": {"name": "sim", "distribution": "aatest", "version": "0.1.0"}},
            "seed": 42, "sensors": sensors, "aatest_version": "0.1.0",
            "started_utc": "2026-11-21T06:00:00Z", "operator": "A. Tester <script>x</script>",
            "table_serial": "TT-2207", "ambient_c": 22.4,
        },
        "figures": {"noise": {"psd": _SVG}},
    }


def typed_results() -> RunResults:
    """:func:`make_results` as the typed record (a fresh one on every call)."""
    return RunResults.model_validate(make_results())


def decided(results: dict[str, Any] | RunResults, acceptance: Acceptance | None = None
            ) -> RunResults:
    """The results after the engine's uncertainty and verdict stages (datasheet defaults)."""
    typed = results if isinstance(results, RunResults) else RunResults.model_validate(results)
    sheets = {ch: SensorDatasheet(model="sr207-aamu") for ch in CHANNELS}
    apply_uncertainty(typed)
    return apply_verdicts(typed, sheets, acceptance or Acceptance())
