"""Uniform sample grids and fast exact sinusoids on them.

Both loggers sample uniformly in lab time (the DAQ's crystal is merely scaled), so every
sinusoid the twin needs — sine profiles, motor-vibration tones — is exp(i(a + b·k)) on a
uniform grid. Splitting k = B·m + j turns that into one complex product per sample of two
short tables instead of a transcendental call per sample (≈ 5× faster, exact to rounding).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from aatest.twin.fastmath import sincos32

_BLOCK = 512

#: the time arrays of the last few grids, by the bits of (start, dt) and n: a step's DAQ grid
#: is built as a separate Grid by each stage that needs its times (the outer axis, the inner
#: axis, the sensor temperature, the truth), each of which would compute the same array
_TIMES_KEPT = 4
_TIMES_MIN_SAMPLES = 4096
_times: dict[tuple[str, str, int], np.ndarray] = {}
_times_lock = threading.Lock()


@dataclass(frozen=True)
class Grid:
    """n samples at lab times start_s + k·dt_s."""

    start_s: float
    dt_s: float
    n: int

    @cached_property
    def times(self) -> np.ndarray:
        """Lab times of the samples (s), read-only: shared by equal grids."""
        key = (float(self.start_s).hex(), float(self.dt_s).hex(), int(self.n))
        with _times_lock:
            times = _times.get(key)
        if times is not None:
            return times
        # start + dt·k in one float64 buffer: k as float64 is exact (n < 2^53), the very
        # operand the integer arange was promoted to, and a + b, a·b commute bit for bit
        times = np.arange(self.n, dtype=np.float64)
        times *= self.dt_s
        times += self.start_s
        times.flags.writeable = False
        if self.n < _TIMES_MIN_SAMPLES:  # (a status poll's one sample evicts nothing)
            return times
        with _times_lock:
            _times[key] = times
            while len(_times) > _TIMES_KEPT:
                del _times[next(iter(_times))]
        return times

    def shifted(self, by_s: float) -> Grid:
        """The same grid ``by_s`` seconds later."""
        return Grid(self.start_s + by_s, self.dt_s, self.n)

    def tone_sum(self, omega_rad_s: np.ndarray, phase_rad: np.ndarray,
                 weights: np.ndarray) -> np.ndarray:
        """Σ_k w_ok·exp(i(ω_k t + φ_k)) for several weight rows o at once: complex (o, n).

        The block split makes the sum over K tones one small complex matrix product
        ((o·rows × K) @ (K × B)) instead of K full-length passes per output.
        """
        omega = np.asarray(omega_rad_s, dtype=float)
        weights = np.atleast_2d(weights)
        rows = -(-self.n // _BLOCK)
        coarse = np.exp(1j * (np.outer(np.arange(rows) * (_BLOCK * self.dt_s), omega)
                              + omega * self.start_s + phase_rad))          # (rows, K)
        fine = np.exp(1j * np.outer(omega * self.dt_s, np.arange(_BLOCK)))  # (K, B)
        stacked = (coarse[None, :, :] * weights[:, None, :]).reshape(-1, omega.size)
        return (stacked @ fine).reshape(weights.shape[0], -1)[:, : self.n]

    def phasor(self, omega_rad_s: float, phase_rad: float = 0.0) -> np.ndarray:
        """exp(i·(ω·t + φ)) at the grid times, complex (n,)."""
        a = omega_rad_s * self.start_s + phase_rad
        b = omega_rad_s * self.dt_s
        rows = -(-self.n // _BLOCK)
        coarse = np.exp(1j * (a + b * _BLOCK * np.arange(rows)))
        fine = np.exp(1j * b * np.arange(_BLOCK))
        return np.multiply.outer(coarse, fine).ravel()[: self.n]


def sincos_deg(angle_deg: np.ndarray, moving: bool,
               ref_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """(sin, cos) of an angle; for an axis held at ``ref_deg`` (tiny vibration/drift only) a
    first-order expansion is exact to ~1e-11 and avoids two transcendental passes."""
    if moving:  # single precision suffices: these only rotate small outer-axis/gravity terms
        return sincos32(np.radians(angle_deg))
    s0, c0 = np.sin(np.radians(ref_deg)), np.cos(np.radians(ref_deg))
    delta = np.radians(angle_deg - ref_deg)
    return s0 + c0 * delta, c0 - s0 * delta
