"""Logger effects: DAQ clock drift (from the sync edges) and excess white output noise.

``clock_drift`` is measured, not fitted: the freeze-pulse edges give the DAQ/table clock rate
ratio of every step (docs/interfaces.md §4 "Clocks"); the evidence is how much worse the replay is
when the two loggers are assumed to share one clock. It is a finding only beyond the rig's
stated clock tolerance (default 20 ppm).

``excess_noise`` is white noise added after the logger's pre-sample filter (slip ring): the
sensor's own noise is band-limited by that filter, so the residual spectrum's floor far above
the filter corner measures the excess directly. Without a pre-sample filter the floor is
compared with the sensor's stated noise.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import signal

from aatest.clocksync.edges import joint_slope_range
from aatest.diagnose.candidates.base import Z95, Context, replace_spec

DEFAULT_CLOCK_TOLERANCE_PPM = 20.0
#: search range of a drift fitted from the phase trend (ppm)
MAX_DRIFT_PPM = 2000.0
#: a white floor below this is ADC quantisation and numerical noise, not an effect (V)
MIN_EXCESS_RMS_V = 2e-4
#: a white floor within this factor of the stated converter's q/√12 is its quantisation noise
QUANTISATION_MARGIN = 2.0
#: without a pre-sample filter, noise must exceed the stated sensor noise by this factor
NOISE_MARGIN = 1.25
#: Welch segment (samples) of the residual spectrum; shorter records are left out
WELCH_SEGMENT = 1024


def _linear_detrend(x: np.ndarray) -> np.ndarray:
    """Remove a straight line (what ``detrend="linear"`` does; scipy-stubs mistype that name)."""
    return np.asarray(signal.detrend(x, type="linear"))


@dataclass(frozen=True)
class DriftEstimate:
    drift_ppm: float
    u_ppm: float
    steps: int
    #: drifts every step's edges allow when they have no latch times (ppm): a hard bound
    range_ppm: tuple[float, float] | None = None


def clock_drift(ctx: Context) -> DriftEstimate | None:
    """DAQ clock drift over steps (ppm) from the sync relations: the weighted mean of the
    latched steps' drifts, or without latch times the centre of the drifts every step's edge
    intervals allow (:func:`~aatest.clocksync.edges.joint_slope_range`, one crystal)."""
    rel = [s.relation for s in ctx.replay.steps if s.relation is not None]
    if not rel:
        return None
    joint = joint_slope_range(rel) if not any(r.latched for r in rel) else None
    if joint is not None:
        lo, hi = ((b - 1.0) * 1e6 for b in joint)
        return DriftEstimate(0.5 * (lo + hi), (hi - lo) / float(np.sqrt(12.0)), len(rel),
                             (lo, hi))
    d = np.array([r.drift_ppm for r in rel])
    u = np.array([max(getattr(r, "drift_u_ppm", 0.0), 1e-3) for r in rel])
    w = 1.0 / u**2
    mean = float(np.sum(w * d) / np.sum(w))
    spread = float(d.std(ddof=1) / np.sqrt(d.size)) if d.size > 1 else 0.0
    return DriftEstimate(mean, max(float(np.sqrt(1.0 / np.sum(w))), spread), d.size)


def phase_trend_drift(ctx: Context, from_start: bool = True, limit_ppm: float = 2000.0,
                      bounds_ppm: tuple[float, float] | None = None
                      ) -> tuple[float, list[float], Any] | None:
    """DAQ drift (ppm) beyond the data's alignment, its 95 % interval and the fit.

    A clock-rate error makes the sensor's phase slide linearly through each record; the
    replay warped by −drift explains it. ``from_start``: the loggers are aligned at the
    trigger only (no edges), so the warp pivots on the record start and per-step offsets are
    dropped; otherwise the warp pivots on the record middle, on top of the edge alignment.
    ``bounds_ppm``: the drift beyond the alignment is searched in this interval (what the edges
    allow) instead of ±``limit_ppm``.
    """
    from aatest.diagnose.candidates.base import curvature_ci, scalar_search

    if not ctx.dynamic_steps:
        return None
    base = ctx.current.spec
    if from_start:
        base = replace_spec(base, delay_s=0.0, step_shift_s=(), warp_from_start=True)

    def make(w: float):
        return replace_spec(base, warp_ppm=w)

    w_lo, w_hi = (-bounds_ppm[1], -bounds_ppm[0]) if bounds_ppm else (-limit_ppm, limit_ppm)
    w, fit = scalar_search(ctx, make, w_lo, w_hi, list(np.linspace(w_lo, w_hi, 21)), xtol=0.01)
    ci = curvature_ci(ctx, make, w, max(0.005 * (w_hi - w_lo), 0.1))
    return -w, [-ci[1], -ci[0]], fit


def one_clock_fit(ctx: Context, drift_ppm: float):
    """The current model replayed as if the DAQ shared the table clock (drift ignored)."""
    return ctx.fit(replace_spec(ctx.current.spec, warp_ppm=drift_ppm))


def residual_psd(ctx: Context, residuals: dict[int, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Welch PSD (V²/Hz) of the residual averaged over steps."""
    fs = 1.0 / ctx.replay.dt_s
    freq, spectra = np.zeros(1), []
    for r in residuals.values():
        if r.size < WELCH_SEGMENT:
            continue
        freq, p = signal.welch(r, fs=fs, nperseg=WELCH_SEGMENT, detrend=_linear_detrend)
        spectra.append(p)
    if not spectra:
        return np.zeros(1), np.zeros(1)
    return freq, np.mean(spectra, axis=0)


def white_floor_rms_v(ctx: Context, residuals: dict[int, np.ndarray]) -> tuple[float, float]:
    """(white-floor RMS, total in-band noise RMS) of the residual, volts.

    The floor is the median PSD well above the pre-sample filter corner (or over the upper
    half band when there is none), converted to the RMS of white noise over the Nyquist band.
    """
    freq, psd = residual_psd(ctx, residuals)
    fs = 1.0 / ctx.replay.dt_s
    corner = ctx.info.antialias_hz
    lo = 4.0 * corner if corner is not None else 0.25 * fs
    band = (freq >= lo) & (freq <= 0.45 * fs)
    if not band.any():
        return 0.0, 0.0
    floor = float(np.median(psd[band]))
    low = (freq > 1.0) & (freq < min(0.4 * (corner or fs), 0.2 * fs))
    total = float(np.median(psd[low])) if low.any() else floor
    return float(np.sqrt(floor * fs / 2.0)), float(np.sqrt(total * fs / 2.0))


def excess_noise(ctx: Context, residuals: dict[int, np.ndarray], stated_noise_v: float
                 ) -> tuple[float, list[float], str | None, float]:
    """(excess RMS V, 95 % interval, veto reason or None, ΔBIC).

    ΔBIC compares a white floor of fitted variance with the expected floor σ0 (quantisation
    level of the stated converter behind a pre-sample filter, else the stated sensor noise)
    on the samples of the band used: −N·(r − 1 − ln r) + ln N with r = σ̂²/σ0² (a
    one-parameter variance test).
    """
    floor, _ = white_floor_rms_v(ctx, residuals)
    n = sum(r.size for r in residuals.values())
    corner = ctx.info.antialias_hz
    filtered = corner is not None
    # behind a filter the floor's expected level is the converter's: q/√12 of the stated logger
    # (16 bit over ±10 V: 88 µV), within QUANTISATION_MARGIN; never below MIN_EXCESS_RMS_V
    min_excess = max(MIN_EXCESS_RMS_V, QUANTISATION_MARGIN * ctx.converter_step_v / np.sqrt(12.0))
    sigma0 = 0.5 * min_excess if filtered else max(stated_noise_v, 1e-9)
    n_band = n * (0.45 - 4.0 * corner * ctx.replay.dt_s if corner is not None else 0.2) * 2
    ratio = max(floor**2 / sigma0**2, 1e-12)
    dbic = float(-max(n_band, 1.0) * (ratio - 1.0 - np.log(ratio)) * (1 if ratio > 1 else -1)
                 + np.log(max(n_band, 2.0)))
    if filtered:
        value = floor
        veto = (None if value >= min_excess
                else f"no white floor above the pre-sample filter band beyond "
                     f"{min_excess * 1e6:.0f} µV (quantisation and numerical noise)")
    else:
        value = float(np.sqrt(max(floor**2 - stated_noise_v**2, 0.0)))
        veto = None if floor >= NOISE_MARGIN * stated_noise_v else (
            f"white noise {floor * 1e3:.2f} mV is within the stated sensor noise")
    if veto is not None:
        return value, [0.0, 0.0], veto, abs(dbic) if ratio <= 1 else dbic
    rel = Z95 * np.sqrt(2.0 / max(n_band / 10.0, 1.0))
    return value, [value * (1 - rel), value * (1 + rel)], None, dbic
