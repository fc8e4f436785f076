"""Servo tracking, table-side disturbances and the controller's state estimator.

Real motion of one axis = commanded profile through an equivalent closed-loop tracking model
+ position-periodic encoder ripple (1 and 2 cycles/°) + narrow-band motor vibration (motor on)
or slow drift (motor off). Everything is an analytic function of time, so the table log and the
sensor sample the same physical truth on their own clocks (docs/method.md §1.2,
docs/interfaces.md §4 "Table effects").

The logged estimates are what the controller computes: the position estimate (true angle +
estimator noise, quantised to the position resolution) and rate/acceleration as central or
five-point differences of that estimate — which is why the acceleration estimate is noisy
(≈ √6·σ/h²) while the rate estimate is clean (≈ σ/(√2·h)).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np
from scipy import signal

from aatest.twin.fastmath import sincos32, standard_normal
from aatest.twin.grid import Grid
from aatest.twin.model import AxisModel, MotorVibration, RateRipple, TableModel
from aatest.twin.profiles import AxisProfile

#: number of tones that synthesise a narrow vibration band (bandwidth_hz > 0)
BAND_TONES = 4


@dataclass(frozen=True)
class Tones:
    """Sum of sinusoids in acceleration: Σ A_k·sin(2π f_k t + φ_k), °/s² (peak per tone)."""

    frequency_hz: np.ndarray
    amplitude_dps2: np.ndarray
    phase_rad: np.ndarray

    def evaluate(self, grid: Grid) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(angle_deg, rate_dps, accel_dps2) of the vibration, zero-mean in all three."""
        sums = self._sums(grid)
        return -sums[2].imag, -sums[1].real, sums[0].imag

    def add_to(self, grid: Grid, angle_deg: np.ndarray, rate_dps: np.ndarray,
               accel_dps2: np.ndarray) -> None:
        """Add :meth:`evaluate` to the three arrays in place (x − y is x + (−y), bit for bit,
        so the sums are those of adding the evaluated arrays)."""
        sums = self._sums(grid)
        np.subtract(angle_deg, sums[2].imag, out=angle_deg)
        np.subtract(rate_dps, sums[1].real, out=rate_dps)
        np.add(accel_dps2, sums[0].imag, out=accel_dps2)

    def _sums(self, grid: Grid) -> np.ndarray:
        w = 2 * np.pi * self.frequency_hz
        a = self.amplitude_dps2
        return grid.tone_sum(w, self.phase_rad, np.stack([a, a / w, a / (w * w)]))


def make_vibration(model: MotorVibration | None, rng: np.random.Generator) -> Tones | None:
    """A rig's motor vibration: a pure tone, or ``BAND_TONES`` tones spread over the band.

    Tone amplitudes are A/√K so the band carries the power of one tone of peak A.
    """
    if model is None or model.amplitude_dps2 == 0.0:
        return None
    if model.bandwidth_hz == 0.0:
        return Tones(np.array([model.frequency_hz]), np.array([model.amplitude_dps2]),
                     np.array([model.phase_rad]))
    freqs = model.frequency_hz + model.bandwidth_hz * (rng.random(BAND_TONES) - 0.5)
    amps = np.full(BAND_TONES, model.amplitude_dps2 / np.sqrt(BAND_TONES))
    return Tones(freqs, amps, rng.uniform(0, 2 * np.pi, BAND_TONES))


def tracked(profile: AxisProfile, servo_bandwidth_hz: float) -> AxisProfile:
    """Steady-state response of a type-3 tracking loop to the commanded profile.

    H(s) = 1 − (s/ω_b)³/(1 + s/ω_b)³: zero error at constant position and rate, a small
    amplitude/phase error on sines that grows as (f/f_b)³ (≈ 1.5 % at 10 Hz for 40 Hz).
    """
    if profile.amplitude_deg == 0.0 or servo_bandwidth_hz <= 0.0:
        return profile
    x = 1j * profile.frequency_hz / servo_bandwidth_hz
    h = 1.0 - x**3 / (1.0 + x) ** 3
    return replace(profile, amplitude_deg=profile.amplitude_deg * abs(h),
                   phase_rad=profile.phase_rad + float(np.angle(h)))


@dataclass(frozen=True)
class AxisTruth:
    """The real motion of one axis during a step, evaluable at any lab time."""

    profile: AxisProfile
    model: AxisModel
    vibration: Tones | None
    motor_on: bool
    drift_dps: float = 0.0

    def evaluate(self, grid: Grid) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Real (angle_deg, rate_dps, accel_dps2) of the axis on a uniform lab-time grid."""
        angle, rate, accel = self.profile.evaluate(grid)
        for ripple in self.model.rate_ripple if self.profile.moving else ():
            angle, rate, accel = _add_ripple(ripple, angle, rate, accel)
        if self.motor_on and self.vibration is not None:
            self.vibration.add_to(grid, angle, rate, accel)  # (fresh arrays: ours to change)
        elif not self.motor_on and self.drift_dps:
            angle = angle + self.drift_dps * (grid.times - self.profile.t0_s)
            rate = rate + self.drift_dps
        return angle, rate, accel


def _add_ripple(ripple: RateRipple, angle: np.ndarray, rate: np.ndarray, accel: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """θ += a·sin(2π n θ + φ) with exact chain-rule rate/acceleration (docs/interfaces.md §4).

    With ``rejection_bandwidth_hz`` the amplitude and phase follow the servo's disturbance
    sensitivity at the instantaneous ripple frequency (quasi-static: exact at constant rate).
    """
    k = 2 * np.pi * ripple.cycles_per_deg  # rad per degree
    # the ripple is ≈1″: its terms are computed in single precision (relative 3e-7 is plenty)
    phase = np.multiply(k, angle)
    phase += ripple.phase_rad
    sin, cos = sincos32(phase, np.float32)
    a = np.float32(ripple.amplitude_deg)
    if ripple.rejection_bandwidth_hz is None:
        s, c = a * sin, a * cos
    else:
        s, c = _rejected(ripple, rate, a, sin, cos)
    # rate + k·rate·c and accel + k·accel·c − (k·rate)²·s, the same float64 operations in
    # place (a + b is b + a bit for bit): two full-length temporaries instead of seven; s and
    # c promoted to float64 once (exact) instead of inside each of four mixed products
    s, c = s.astype(np.float64), c.astype(np.float64)
    krate = k * rate
    new_rate = krate * c
    new_rate += rate
    new_accel = np.multiply(k, accel)
    new_accel *= c
    new_accel += accel
    krate *= krate
    krate *= s
    new_accel -= krate
    s += angle
    return s, new_rate, new_accel


def _rejected(ripple: RateRipple, rate: np.ndarray, a: np.float32, sin: np.ndarray,
              cos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The ripple's (sine, cosine) terms through the servo's disturbance sensitivity, float32.

    S(jr) = (jr)³/(1 + jr)³ = −j·r³ / (d_re + j·d_im), in real arithmetic for speed; each
    product and sum in place, operands in the order written (a·b is b·a bit for bit).
    """
    assert ripple.rejection_bandwidth_hz is not None
    r = np.abs(rate).astype(np.float32)
    r *= np.float32(ripple.cycles_per_deg / ripple.rejection_bandwidth_hz)
    r2 = r * r
    r3 = r2 * r
    d_re = np.multiply(r2, np.float32(3.0), out=r2)  # 1 − 3·r²
    np.subtract(np.float32(1.0), d_re, out=d_re)
    d_im = np.multiply(r, np.float32(3.0), out=r)  # 3·r − r³
    d_im -= r3
    scale = np.multiply(r3, -a, out=r3)  # (−a)·r³ / (d_re² + d_im²)
    denominator = d_re * d_re
    denominator += np.square(d_im)
    scale /= denominator
    s_re = np.multiply(scale, d_im, out=d_im)
    s_im = np.multiply(scale, d_re, out=d_re)
    s = sin * s_re  # sin·s_re + cos·s_im
    s += np.multiply(cos, s_im, out=denominator)
    c = np.multiply(cos, s_re, out=cos)  # cos·s_re − sin·s_im
    c -= np.multiply(sin, s_im, out=s_im)
    return s, c


def _noisy(values: np.ndarray, sigma: float, rng: np.random.Generator) -> np.ndarray:
    """``values + sigma·N(0, 1)``, a new array (the input itself when ``sigma`` is 0)."""
    if sigma <= 0.0:
        return values
    noise = standard_normal(rng, values.size)
    noise *= sigma
    noise += values  # a + b is b + a bit for bit: no third array
    return noise


def quantise(values: np.ndarray, step: float, in_place: bool = False) -> np.ndarray:
    """Round to a multiple of ``step`` (no-op when step is 0); ``in_place``: in ``values``."""
    if step <= 0.0:
        return values
    counts = np.divide(values, step, out=values if in_place else None)
    np.round(counts, out=counts)
    counts *= step
    return counts


#: stencil half-width needed on each side of the record
STENCIL_PAD = 2


def estimates(
    true_angle_deg: np.ndarray, model: AxisModel, dt_s: float, method: str,
    rng: np.random.Generator,
) -> dict[str, np.ndarray]:
    """Controller log of one axis from the true angle on ``N + 2·STENCIL_PAD`` log samples.

    Returns position estimate, rate and acceleration estimates (differences of the position
    estimate, as the controller computes them) and the raw feedback, each of length N.
    """
    res = model.encoder_resolution_deg
    noisy = _noisy(true_angle_deg, model.estimate_noise_deg, rng)
    counts = noisy  # the controller works in counts
    if res > 0.0:  # (in the noisy array itself when it is a new one)
        counts = np.divide(noisy, res, out=None if noisy is true_angle_deg else noisy)
        np.round(counts, out=counts)
    feedback = _noisy(true_angle_deg, model.encoder_noise_deg, rng)
    raw = quantise(feedback, res, in_place=feedback is not true_angle_deg)
    p = STENCIL_PAD
    n = true_angle_deg.size - 2 * p
    f = [counts[p + k: p + k + n] for k in (-2, -1, 0, 1, 2)]
    quanta = estimate_quanta(model, dt_s, method)
    rate, accel = _stencils(f, method)
    rate *= quanta["rate_dps"]
    accel *= quanta["accel_dps2"]
    return {"position_deg": f[2] * quanta["position_deg"], "rate_dps": rate,
            "accel_dps2": accel, "feedback_deg": raw[p: p + n]}


def _stencils(f: list[np.ndarray], method: str) -> tuple[np.ndarray, np.ndarray]:
    """Rate and acceleration stencils (in counts) of the shifted views ``f`` (k = −2…2).

    Five-point: −f₂ + 8f₁ − 8f₋₁ + f₋₂ and −f₂ + 16f₁ − 30f₀ + 16f₋₁ − f₋₂, evaluated left to
    right as written, in place (x − y is x + (−y) and a + b is b + a, bit for bit).
    """
    if method != "five_point":
        return f[3] - f[1], f[3] - 2 * f[2] + f[1]
    rate = np.multiply(f[3], 8.0)
    rate -= f[4]
    term = np.multiply(f[1], 8.0)
    rate -= term
    rate += f[0]
    accel = np.multiply(f[3], 16.0)
    accel -= f[4]
    np.multiply(f[2], 30.0, out=term)
    accel -= term
    np.multiply(f[1], 16.0, out=term)
    accel += term
    accel -= f[0]
    return rate, accel


def estimate_quanta(model: AxisModel, dt_s: float, method: str) -> dict[str, float]:
    """Value of one count of each controller log channel (deg, °/s, °/s²): the estimates are
    integer combinations of encoder counts times these; with an ideal encoder (resolution 0)
    the "counts" are the angles themselves (deg)."""
    res = model.encoder_resolution_deg or 1.0
    rate_den, accel_den = (12 * dt_s, 12 * dt_s**2) if method == "five_point" else (
        2 * dt_s, dt_s**2)
    return {"position_deg": res, "feedback_deg": res, "rate_dps": res / rate_den,
            "accel_dps2": res / accel_den}


def floor_rocking(table: TableModel, n: int, dt_s: float,
                  rng: np.random.Generator) -> np.ndarray | None:
    """Building vibration: (2, n) band-limited Gaussian rocking about the horizontal lab axes.

    White noise through a Butterworth band-pass, scaled by the filter's noise gain so each
    axis has ``floor_vibration_rms_dps2`` RMS. None when switched off.
    """
    if table.floor_vibration_rms_dps2 <= 0.0:
        return None
    b, a, gain = _band_filter(*table.floor_vibration_band_hz, round(dt_s, 15))
    white = standard_normal(rng, 2 * n).reshape(2, n)
    return signal.lfilter(b, a, white, axis=1) * (table.floor_vibration_rms_dps2 / gain)


@lru_cache(maxsize=8)
def _band_filter(lo_hz: float, hi_hz: float, dt_s: float) -> tuple[np.ndarray, np.ndarray, float]:
    """(b, a, noise gain) of the rocking's band-pass at the log's rate. A log slower than
    twice the band's top sees the rocking folded below its Nyquist frequency: the band is
    then cut at 0.9 × Nyquist (its RMS is set by the gain, so kept), as the amplitude band
    of :func:`aatest.twin.sensor.band_filter` is."""
    top_hz = min(hi_hz, 0.45 / dt_s)
    b, a = signal.butter(2, [min(lo_hz, 0.5 * top_hz), top_hz], btype="bandpass",
                         fs=1.0 / dt_s)
    impulse = signal.lfilter(b, a, np.r_[1.0, np.zeros(8191)])
    return b, a, float(np.sqrt(np.sum(impulse**2)))
