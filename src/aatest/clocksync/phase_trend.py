"""The DAQ clock drift from the sine steps' phase trend, where the sync edges only bound it.

Without latch times an edge is known only to its registering table sample, so a record whose
edges cross fewer than two table samples (|drift| × record < 2 samples) bounds the drift to
about one sample over the record (≈ 61 ppm wide for 8 s at 2 kHz, :mod:`aatest.clocksync.edges`).
The sine steps hold the rest: a drift scales time, so a sensor resampled with a drift ``d′``
where the truth is ``d`` shows, against the table's own record of the same motion, a phase
that slides linearly through the step,

    φ_sensor(t) − φ_table(t) = φ₀ + 2π·f·(d − d′)·t,

whatever the sensor's (constant) gain and phase. The slope over a record of ``T`` seconds at
``f`` Hz resolves ``d`` to about ``σ_φ·√12 / (2π·f·T·√K)`` (``K`` segments, ``σ_φ`` each
segment's phase noise): a few hundredths of a ppm on an 8 s, 8 Hz step of a low-noise sensor.
The steps share one DAQ crystal, so their estimates are combined (inverse-variance); the
edges' feasible range stays a hard bound.

Why a phase trend and not the edges over the whole run: each step is its own record on both
loggers (time stamps restart at every step; the table log starts at the trigger), so the
offsets of different steps are independent unknowns and only their drifts can be pooled.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from aatest.clocksync.relation import ClockRelation, SyncedStep

#: the first part of each record is left out: a sensor's phase settles after the motion starts
#: (the twin's amplitude-dependent damping follows a 2.5 s trailing window; with it, the whole
#: 8 s record read a trend of +2.3 ppm at 32 Hz and latch-corrected clocks, its last three
#: quarters +0.2 ± 0.3)
SETTLE_FRACTION = 0.25
#: segments a step's record is cut into for the phase trend (each holds ≥ one cycle)
MAX_SEGMENTS = 16
#: a trend needs this many segments (a line and its scatter)
MIN_SEGMENTS = 4
#: a sensor channel whose segment phase noise exceeds this (rad) does not see the motion
MAX_SEGMENT_PHASE_NOISE_RAD = 0.02
#: the prefix of the DAQ's sensor channels (volts)
SENSOR_PREFIX = "v_"


@dataclass(frozen=True)
class PhaseTrend:
    """The drift a synchronised step's sensor phase still slides by, and its basis."""

    step: str
    #: drift the step was synchronised with (ppm) plus the trend: the step's own estimate
    drift_ppm: float
    #: standard uncertainty (ppm)
    u_ppm: float
    channel: str
    frequency_hz: float
    segments: int


def _segment_phasors(x: np.ndarray, t_s: np.ndarray, f_hz: float, segments: int
                     ) -> tuple[np.ndarray, np.ndarray]:
    """(complex amplitude at ``f_hz``, residual RMS) of each of ``segments`` equal segments.

    Each segment is fitted with ``a·cos + b·sin + c + e·t`` (a slow offset and ramp of the
    position left free), in one batched least-squares solve.
    """
    length = x.size // segments
    xs = x[: length * segments].reshape(segments, length)
    ts = t_s[: length * segments].reshape(segments, length)
    tc = ts - ts.mean(axis=1, keepdims=True)
    w = 2.0 * np.pi * f_hz * ts
    design = np.stack([np.cos(w), np.sin(w), np.ones_like(ts), tc], axis=2)  # (K, L, 4)
    normal = np.einsum("kli,klj->kij", design, design)
    rhs = np.einsum("kli,kl->ki", design, xs)
    coef = np.linalg.solve(normal, rhs[..., None])[..., 0]
    residual = xs - np.einsum("kli,ki->kl", design, coef)
    return coef[:, 0] - 1j * coef[:, 1], np.sqrt(np.mean(residual**2, axis=1))


def _trend(sensor: np.ndarray, reference: np.ndarray, t_s: np.ndarray, f_hz: float,
           segments: int) -> tuple[float, float] | None:
    """(slope rad/s, its standard uncertainty) of the sensor's phase against the reference's,
    or None when the sensor does not see the motion."""
    zs, rs = _segment_phasors(sensor, t_s, f_hz, segments)
    zr, rr = _segment_phasors(reference, t_s, f_hz, segments)
    length = sensor.size // segments
    # a segment's phase noise: residual over amplitude, over √(L/2) independent samples
    noise = np.hypot(rs / np.abs(zs), rr / np.abs(zr)) / np.sqrt(0.5 * length)
    if not np.all(np.isfinite(noise)) or float(np.max(noise)) > MAX_SEGMENT_PHASE_NOISE_RAD:
        return None
    phase = np.unwrap(np.angle(zs * np.conj(zr)))
    tk = t_s[: length * segments].reshape(segments, length).mean(axis=1)
    tk = tk - tk.mean()
    sxx = float(tk @ tk)
    slope = float(tk @ (phase - phase.mean())) / sxx
    scatter = phase - phase.mean() - slope * tk
    sigma = max(float(np.sqrt(np.mean(noise**2))),
                float(np.sqrt(scatter @ scatter / (segments - 2))))
    return slope, sigma / np.sqrt(sxx)


def _reference(synced: SyncedStep, first: int) -> np.ndarray | None:
    """The table's own record of the step's motion: encoder position, else its acceleration."""
    axis = synced.step.axis if synced.step.axis in ("inner", "outer") else "inner"
    for name in (f"{axis}_position_deg", f"{axis}_accel_dps2"):
        if name in synced.table:
            values = np.asarray(synced.table[name], dtype=np.float64)[first:]
            if values.size and np.all(np.isfinite(values)):
                return values
    return None


def step_phase_trend(synced: SyncedStep) -> PhaseTrend | None:
    """The drift a synchronised sine step's sensors show against the table (module docstring).

    None for a step that is not a sine, holds fewer than :data:`MIN_SEGMENTS` cycles, has no
    table record of its motion or no sensor that sees it. The most precise sensor channel is
    taken (channels of one DAQ share its clock).
    """
    step = synced.step
    f_hz = float(step.frequency_hz or 0.0)
    if step.kind != "sine" or f_hz <= 0.0 or synced.record is not None:
        return None
    first = int(SETTLE_FRACTION * len(synced.time_s))
    t_s = np.asarray(synced.time_s, dtype=np.float64)[first:]
    segments = min(MAX_SEGMENTS, int(np.floor(f_hz * (t_s[-1] - t_s[0]))) if t_s.size else 0)
    reference = _reference(synced, first)
    if segments < MIN_SEGMENTS or reference is None:
        return None
    best: tuple[float, float, str] | None = None
    for name in (c for c in synced.daq if c.startswith(SENSOR_PREFIX)):
        found = _trend(np.asarray(synced.daq[name], dtype=np.float64)[first:], reference, t_s,
                       f_hz, segments)
        if found is not None and (best is None or found[1] < best[1]):
            best = (found[0], found[1], name)
    if best is None:
        return None
    scale = 1e6 / (2.0 * np.pi * f_hz)
    return PhaseTrend(step.id, synced.relation.drift_ppm + best[0] * scale, best[1] * scale,
                      best[2], f_hz, segments)


def combined_drift(trends: Iterable[PhaseTrend]) -> tuple[float, float] | None:
    """(drift ppm, standard uncertainty ppm) of one crystal from the steps' phase trends.

    The inverse-variance mean; its uncertainty is widened by the scatter of the steps about it
    (Birge ratio) when they disagree more than their own uncertainties say.
    """
    found = list(trends)
    if not found:
        return None
    d = np.array([t.drift_ppm for t in found])
    w = 1.0 / np.array([max(t.u_ppm, 1e-6) for t in found]) ** 2
    mean = float(np.sum(w * d) / np.sum(w))
    u = float(np.sqrt(1.0 / np.sum(w)))
    if d.size > 1:
        birge = float(np.sqrt(np.sum(w * (d - mean) ** 2) / (d.size - 1)))
        u *= max(1.0, birge)
    return mean, u


def trend_slope_range(trend: tuple[float, float], edges: tuple[float, float] | None,
                      coverage: float = np.sqrt(3.0)) -> tuple[float, float] | None:
    """Slopes (1 + drift) the phase trend allows, as a uniform interval of the same standard
    uncertainty (±√3·u), inside the edges' range ``edges``; None when the two do not meet
    (the trend contradicts the edges: not a clock effect, so the edges stand)."""
    d, u = trend
    lo, hi = 1.0 + (d - coverage * u) * 1e-6, 1.0 + (d + coverage * u) * 1e-6
    if edges is not None:
        lo, hi = max(lo, edges[0]), min(hi, edges[1])
    return (lo, hi) if lo < hi else None


#: a record whose edges cross at least this many table samples fixes the drift itself
#: (docs/method.md §2: two crossings a known number of samples apart)
MIN_CROSSINGS = 2.0


def edges_fix_drift(relation: ClockRelation, table_dt_s: float) -> bool:
    """Whether the step's edges cross ≥ :data:`MIN_CROSSINGS` table samples for every drift
    they allow: then the edges fix the drift (within 0.5 ppm over three 8 s steps at ±130 to
    ±150 ppm on the twin), better than the trend of a low-frequency sine, and stand alone.

    Without it (|drift| × record < 2 samples) they only bound it and the trend is used.
    """
    if relation.latched or relation.slope_range is None or relation.fit_span_daq_s is None:
        return False
    lo, hi = (b - 1.0 for b in relation.slope_range)
    least = 0.0 if lo <= 0.0 <= hi else min(abs(lo), abs(hi))
    span_s = relation.fit_span_daq_s[1] - relation.fit_span_daq_s[0]
    return least * span_s / table_dt_s >= MIN_CROSSINGS


def trends_of(steps: Iterable[SyncedStep]) -> Mapping[str, PhaseTrend]:
    """The phase trend of every step that shows one, by step id."""
    return {t.step: t for t in (step_phase_trend(s) for s in steps) if t is not None}
