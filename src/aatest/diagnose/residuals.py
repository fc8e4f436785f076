"""Where the nominal replay is wrong: residual views a person can read (numbers for the JSON).

Residual = measured − simulated, for the nominal model and for the extended one (the named
effects and the generic extensions the JSON reports):
RMS per step; the residual spectrum's strongest lines, each classified as a harmonic of the
step's excitation, rate-scaled (a fixed number of cycles per degree of table angle) or
unrelated; and residual RMS binned against |acceleration|, |rate|, |jerk|, temperature, time
within the record, table orientation and moving axis.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy import signal

from aatest.diagnose.candidates.base import Context
from aatest.diagnose.generic import SEEN_BY_TABLE, table_line_dps2
from aatest.diagnose.noise_floor import NoiseFloor
from aatest.diagnose.replay import StepReplay, sensor_acceleration

_BINS = 6
#: higher multiples of a slow excitation are not called its harmonics
_MAX_HARMONIC = 10
_LINES = 5
#: a spectral line stands this far above the median level of its step's residual spectrum
_LINE_SNR = 20.0
#: a line within this fraction of an integer multiple of the excitation is its harmonic
_HARMONIC_TOL = 0.02


def _classify(f_hz: float, sr: StepReplay) -> str:
    f0 = sr.inner.frequency_hz or sr.outer.frequency_hz
    if f0 > 0:
        k = f_hz / f0
        if 1 <= round(k) <= _MAX_HARMONIC and abs(k - round(k)) < _HARMONIC_TOL:
            return f"harmonic {round(k)} of {f0:.3f} Hz"
    rate = abs(sr.inner.rate_dps) or abs(sr.outer.rate_dps)
    if rate > 0:
        return f"rate-scaled: {f_hz / rate:.3f} cycles/deg at {rate:g} °/s"
    return "unrelated to the excitation"


def _source(f_hz: float, amplitude_v: float, sr: StepReplay, scale_v_per_dps2: float) -> str:
    """Whether the table's position log shows the line too (motion) or only the sensor."""
    seen = table_line_dps2(sr, f_hz) >= SEEN_BY_TABLE * amplitude_v / abs(scale_v_per_dps2)
    return "in the table log too" if seen else "sensor only"


def spectrum_lines(ctx: Context, residuals: dict[int, np.ndarray]) -> list[dict[str, Any]]:
    """Strongest narrow lines of the residual spectrum per step, classified against the
    excitation (harmonic, rate-scaled, unrelated) and the table log (motion, sensor only)."""
    fs = 1.0 / ctx.replay.dt_s
    lines: list[dict[str, Any]] = []
    for sr in ctx.replay.steps:
        # one segment: detrending the record first is periodogram's detrend="linear"
        r = signal.detrend(np.asarray(residuals[sr.index], dtype=np.float64), type="linear")
        f, p = signal.periodogram(r, fs=fs, detrend=False, window="hann")
        floor = float(np.median(p[1:])) or 1e-30
        idx, _ = signal.find_peaks(p, height=_LINE_SNR * floor, distance=8)
        for i in idx[np.argsort(p[idx])[::-1][:_LINES]]:
            amp = float(np.sqrt(2.0 * p[i] * fs / r.size * 1.5))
            lines.append({"step": sr.step.id, "frequency_hz": float(f[i]),
                          "amplitude_v": amp, "snr": float(p[i] / floor),
                          "class": _classify(float(f[i]), sr)})
    lines.sort(key=lambda d: -d["amplitude_v"])
    steps = {sr.step.id: sr for sr in ctx.replay.steps}
    scale = ctx.info.nominal_scale_v_per_dps2
    for line in lines[:20]:
        line["source"] = _source(line["frequency_hz"], line["amplitude_v"], steps[line["step"]],
                                 scale)
        line["class"] += f", {line['source']}"
    return lines[:20]


def _binned(x: np.ndarray, r: np.ndarray) -> list[dict[str, float]]:
    """Residual RMS in quantile bins of ``x``."""
    edges = np.unique(np.quantile(x, np.linspace(0, 1, _BINS + 1)))
    if edges.size < 2:  # noqa: PLR2004 - one distinct value: a single bin, no edges between
        rms = float(np.sqrt(np.mean(r * r)))
        return [{"from": float(edges[0]), "to": float(edges[0]), "rms_v": rms}]
    which = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, edges.size - 2)
    out = []
    for b in range(edges.size - 1):
        m = which == b
        if m.any():
            out.append({"from": float(edges[b]), "to": float(edges[b + 1]),
                        "rms_v": float(np.sqrt(np.mean(r[m] ** 2)))})
    return out


def _against(ctx: Context, residuals: dict[int, np.ndarray]) -> dict[str, Any]:
    cols: dict[str, list[np.ndarray]] = {k: [] for k in ("accel", "rate", "jerk", "temp", "time")}
    res = []
    for sr in ctx.replay.steps:
        step = slice(None, None, 8)
        t = sr.time_s[step]
        a = sensor_acceleration(sr, ctx.info.axis, t)[2]
        m = sr.motion(t)
        cols["accel"].append(np.abs(a))
        cols["rate"].append(np.abs(m["inner_rate"]) + np.abs(m["outer_rate"]))
        cols["jerk"].append(np.abs(np.gradient(a, sr.dt_s * 8)))
        temp = sr.temperature_c[step] if sr.temperature_c is not None else np.zeros_like(t)
        cols["temp"].append(temp)
        cols["time"].append(t / max(sr.time_s[-1], 1e-9))
        res.append(residuals[sr.index][step])
    r = np.concatenate(res)
    names = {"accel": "abs_accel_dps2", "rate": "abs_rate_dps", "jerk": "abs_jerk_dps3",
             "temp": "temperature_c", "time": "time_fraction_of_record"}
    return {names[k]: _binned(np.concatenate(v), r) for k, v in cols.items()}


def _by_group(ctx: Context, residuals: dict[int, np.ndarray], key) -> dict[str, float]:
    acc: dict[str, list[np.ndarray]] = {}
    for sr in ctx.replay.steps:
        acc.setdefault(key(sr), []).append(residuals[sr.index])
    return {k: float(np.sqrt(np.mean(np.concatenate(v) ** 2))) for k, v in acc.items()}


def residual_views(ctx: Context, r0: dict[int, np.ndarray], r1: dict[int, np.ndarray],
                   floor: NoiseFloor | None = None) -> dict[str, Any]:
    """All residual views of one channel, before (nominal: ``r0``) and after (``r1``, the
    model the JSON reports: named effects and generic extensions together), per step index.

    With ``floor``, each step's row also carries its own noise floor (V RMS).
    """
    per_step = []
    for sr in ctx.replay.steps:
        row = {"step": sr.step.id, "kind": sr.step.kind,
               "rms_v_nominal": float(np.sqrt(np.mean(r0[sr.index] ** 2))),
               "rms_v_extended": float(np.sqrt(np.mean(r1[sr.index] ** 2)))}
        if floor is not None:
            row["noise_floor_v"] = floor.per_step_v.get(sr.step.id, floor.rms_v)
        per_step.append(row)
    return {
        "per_step": per_step,
        "spectrum_lines": spectrum_lines(ctx, r0),
        "spectrum_lines_extended": spectrum_lines(ctx, r1),
        "against": _against(ctx, r0),
        "by_orientation": _by_group(ctx, r0, lambda s: f"outer {s.outer.offset_deg:.0f}°, "
                                                        f"inner {s.inner.offset_deg:.0f}°"),
        "by_axis": _by_group(ctx, r0, lambda s: s.step.axis),
    }
