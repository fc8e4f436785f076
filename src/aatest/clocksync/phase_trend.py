"""The DAQ clock drift from the sine steps' phase trend, where the sync edges only bound it.

Without latch times an edge is known only to its registering table sample, so a record whose
edges cross fewer than two table samples (|drift| × record < 2 samples) bounds the drift to
about one sample over the record (≈ 61 ppm wide for 8 s at 2 kHz, :mod:`aatest.clocksync.edges`).
The sine steps hold the rest: a drift scales time, so a sensor resampled with a drift ``d′``
where the truth is ``d`` shows, against the table's own record of the same motion, a phase
that slides linearly through the step,

    φ_sensor(t) − φ_table(t) = φ₀ + 2π·f·(d − d′)·t,

whatever the sensor's (constant) gain and phase. The step is fitted whole, sensor and encoder
alike, as a sine whose complex amplitude moves linearly through the record, ``x ≈ Re{(c₀ +
c₁·t)·e^{iωt}}``, plus its first harmonics and a cubic bias (one linear least-squares solve,
Tukey-weighted): the phase slope is ``Im(c₁/c₀)``. Its uncertainty comes from the residual's
noise density next to ``f`` (Welch), so coloured noise counts as what it is at ``f``: ``u ≈
√(12·S(f)/T³)/(A·2π·f)`` (``S`` the one-sided density, ``A`` the amplitude), a tenth of a ppm
or two on an 8 s, 8 Hz step of the realistic sensor.

What the phase wanders by, on the twin's realistic sensor (each effect switched off in turn,
three 8.2 s sines at 1, 4 and 8 Hz, last three quarters cut into 0.4 s segments): 0.17 mrad RMS
per segment at 8 Hz, 0.08 mrad with the table's 35 Hz motor vibration off, 0.015 mrad with the
sensor's 1 mV noise off too. The vibration is real motion the sensor sees as acceleration and
the encoder, as position, (f/35 Hz)² weaker; a rectangular 0.4 s segment leaks ≈ 3 % of it into
the ``f`` bin, the whole record's hard ends still ≈ 0.2 % (≈ 0.9 ppm of trend at 4 Hz on seed
1, gone with the vibration off), a record tapered over a fifth of its length none that shows.
The noise passes the DAQ's 100 Hz pre-sample filter, so its density at ``f`` is ≈ √10 times
that of white noise of the same RMS (0.1 mrad per segment, not the 0.03 a white-noise estimate
from the residual's RMS says). Neither the amplitude-dependent damping nor the bias drift,
ripple or floor vibration moved the scatter; the damping makes the settling the first quarter
leaves out (≈ 0.7 mrad at 8 Hz in the first 0.4 s, gone after ≈ 2 s).

The steps share one DAQ crystal, so their estimates are combined (inverse-variance; steps whose
u is more than :data:`POOL_U_RATIO` times the best one's are left out); the edges' feasible
range stays a hard bound.

Why a phase trend and not the edges over the whole run: each step is its own record on both
loggers (time stamps restart at every step; the table log starts at the trigger), so the
offsets of different steps are independent unknowns and only their drifts can be pooled.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np
from scipy import signal

from aatest.clocksync.relation import ClockRelation, SyncedStep

#: the first part of each record is left out: a sensor's phase settles after the motion starts
#: (the twin's amplitude-dependent damping follows a 2.5 s trailing window; with it, the whole
#: 8 s record read a trend of +2.3 ppm at 32 Hz and latch-corrected clocks, its last three
#: quarters +0.2 ± 0.3)
SETTLE_FRACTION = 0.25
#: a trend needs this many cycles after the settling part (a phase and its slope)
MIN_CYCLES = 4
#: harmonics of ``f`` fitted beside it (a sensor's nonlinearity and hysteresis, the table's
#: position-periodic ripple): modelled, they do not leak into the phase at ``f``
HARMONICS = 5
#: degree of the bias polynomial fitted beside the sine (warm-up, drift)
BIAS_DEGREE = 3
#: a channel whose record phase is uncertain by more than this (rad) does not see the motion
#: (0.02 rad per cycle-long segment of the former segment fit, over 16 of them)
MAX_PHASE_NOISE_RAD = 0.005
#: the fit's weight tapers to zero over this fraction of the record (Tukey): a record's hard
#: ends leak a far line (the table's 35 Hz vibration, which the encoder hardly sees) into the
#: moving amplitude as 1/(Δf·T), a tapered one as 1/(Δf·T)³
TAPER_FRACTION = 0.2
#: Welch segment length for the noise density next to ``f`` (s; shorter records: half)
NOISE_SEGMENT_S = 4.0
#: the noise density is averaged over ``f ± max(2 Hz, f/2)``, harmonics and DC left out
NOISE_BAND_HZ = 2.0
#: a noise density is averaged over at least this many Welch bins
MIN_NOISE_BINS = 3
#: steps whose u exceeds the best step's by more than this are not pooled: their weight would be
#: < 1/9 of it, and a slow sine's few cycles leave its u the least reliable (1 Hz steps of the
#: realistic sensor: 8 cycles, errors up to 2.8 u against 0.9 u at 4 and 8 Hz)
POOL_U_RATIO = 3.0
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
    #: cycles of the sine the trend was fitted on
    cycles: int


def _design(t_s: np.ndarray, f_hz: float) -> tuple[np.ndarray, float]:
    """The whole-step design (module docstring) and its time half-span (s): columns
    ``cos, sin, τ·cos, τ·sin`` of ``f``, cos/sin of its harmonics, ``τ⁰ … τ^BIAS_DEGREE``
    (τ = time from the record's centre over the half-span, for conditioning)."""
    half_s = 0.5 * float(t_s[-1] - t_s[0])
    tau = (t_s - 0.5 * float(t_s[-1] + t_s[0])) / half_s
    w = 2.0 * np.pi * f_hz * t_s
    cols = [np.cos(w), np.sin(w), tau * np.cos(w), tau * np.sin(w)]
    for h in range(2, HARMONICS + 1):
        cols += [np.cos(h * w), np.sin(h * w)]
    cols += [tau**p for p in range(BIAS_DEGREE + 1)]
    return np.column_stack(cols), half_s


def _noise_variance(residual: np.ndarray, fs_hz: float, f_hz: float) -> float:
    """The residual's per-sample variance of white noise with its density next to ``f``
    (Welch, harmonics and DC left out): what the fit's covariance must be scaled by."""
    nperseg = int(min(residual.size // 2, NOISE_SEGMENT_S * fs_hz))
    freq, psd = signal.welch(residual, fs=fs_hz, nperseg=nperseg)
    df = float(freq[1])
    band = (np.abs(freq - f_hz) < max(NOISE_BAND_HZ, 0.5 * f_hz)) & (freq > 3.0 * df)
    for h in range(1, HARMONICS + 1):
        band &= np.abs(freq - h * f_hz) > 2.5 * df
    if np.count_nonzero(band) < MIN_NOISE_BINS:  # a slow sine: harmonics fill the band,
        # read above them
        band = (freq > HARMONICS * f_hz + 2.5 * df) & (freq < HARMONICS * f_hz + 5.0)
    return float(np.mean(psd[band])) * 0.5 * fs_hz


def _slope(x: np.ndarray, t_s: np.ndarray, f_hz: float, fs_hz: float
           ) -> tuple[float, float, float]:
    """(phase slope rad/s, its standard uncertainty, the record phase's) of one channel."""
    design, half_s = _design(t_s, f_hz)
    weight = signal.windows.tukey(x.size, TAPER_FRACTION)
    weighted = design * weight[:, None]
    inverse = np.linalg.inv(weighted.T @ design)
    coef = inverse @ (weighted.T @ x)
    variance = _noise_variance(x - design @ coef, fs_hz, f_hz)
    cov = variance * (inverse @ (weighted.T @ weighted) @ inverse.T)[:4, :4]
    a0, b0, a1, b1 = coef[:4]
    power = half_s * (a0 * a0 + b0 * b0)
    slope = (a1 * b0 - b1 * a0) / power  # Im(c₁/c₀), c = a − i·b, c₁ per second
    grad = np.array([-b1 - 2.0 * half_s * a0 * slope, a1 - 2.0 * half_s * b0 * slope,
                     b0, -a0]) / power
    u_phase = float(np.sqrt(0.5 * (cov[0, 0] + cov[1, 1]) / (a0 * a0 + b0 * b0)))
    return float(slope), float(np.sqrt(grad @ cov @ grad)), u_phase


def _trend(sensor: np.ndarray, reference: np.ndarray, t_s: np.ndarray, f_hz: float,
           fs_hz: float) -> tuple[float, float] | None:
    """(slope rad/s, its standard uncertainty) of the sensor's phase against the reference's,
    or None when the sensor does not see the motion."""
    found = _slope(sensor, t_s, f_hz, fs_hz)
    if not all(np.isfinite(found)) or found[2] > MAX_PHASE_NOISE_RAD:
        return None
    ref = _slope(reference, t_s, f_hz, fs_hz)
    return found[0] - ref[0], float(np.hypot(found[1], ref[1]))


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

    None for a step that is not a sine, holds fewer than :data:`MIN_CYCLES` cycles, has no
    table record of its motion or no sensor that sees it. The most precise sensor channel is
    taken (channels of one DAQ share its clock).
    """
    step = synced.step
    f_hz = float(step.frequency_hz or 0.0)
    if step.kind != "sine" or f_hz <= 0.0 or synced.record is not None:
        return None
    first = int(SETTLE_FRACTION * len(synced.time_s))
    t_s = np.asarray(synced.time_s, dtype=np.float64)[first:]
    cycles = int(np.floor(f_hz * (t_s[-1] - t_s[0]))) if t_s.size else 0
    reference = _reference(synced, first)
    if cycles < MIN_CYCLES or reference is None:
        return None
    best: tuple[float, float, str] | None = None
    for name in (c for c in synced.daq if c.startswith(SENSOR_PREFIX)):
        found = _trend(np.asarray(synced.daq[name], dtype=np.float64)[first:], reference, t_s,
                       f_hz, float(synced.sample_rate_hz))
        if found is not None and (best is None or found[1] < best[1]):
            best = (found[0], found[1], name)
    if best is None:
        return None
    scale = 1e6 / (2.0 * np.pi * f_hz)
    return PhaseTrend(step.id, synced.relation.drift_ppm + best[0] * scale, best[1] * scale,
                      best[2], f_hz, cycles)


def combined_drift(trends: Iterable[PhaseTrend]) -> tuple[float, float] | None:
    """(drift ppm, standard uncertainty ppm) of one crystal from the steps' phase trends.

    The inverse-variance mean of the steps whose u is within :data:`POOL_U_RATIO` of the best;
    its uncertainty is widened by the scatter of the steps about it (Birge ratio) when they
    disagree more than their own uncertainties say.
    """
    found = list(trends)
    if not found:
        return None
    best = min(t.u_ppm for t in found)
    found = [t for t in found if t.u_ppm <= POOL_U_RATIO * best]
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
