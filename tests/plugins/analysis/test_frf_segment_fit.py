"""The FRF segment fit's fundamentals against a direct weighted least-squares solution."""

from __future__ import annotations

import numpy as np
import pytest

from aatest.plugins.analysis import frf


def _direct_fundamentals(segments: np.ndarray, frequency_hz: float, fs_hz: float,
                         harmonics: int) -> np.ndarray:
    """The Hann-weighted least-squares fit of each segment by ``np.linalg.lstsq`` (SVD)."""
    length = segments.shape[1]
    omega_tau = 2.0 * np.pi * frequency_hz / fs_hz * np.arange(length)
    k = np.arange(1, harmonics + 1)
    k = k[k * frequency_hz < fs_hz / 2.0]
    angles = np.outer(omega_tau, k)
    design = np.column_stack([np.ones(length), np.cos(angles), np.sin(angles)])
    root_w = np.sqrt(0.5 - 0.5 * np.cos(2.0 * np.pi * np.arange(length) / length))
    coef, *_ = np.linalg.lstsq(design * root_w[:, None], (segments * root_w).T, rcond=None)
    return np.asarray(coef[1] - 1j * coef[1 + k.size])


@pytest.mark.parametrize("frequency_hz", [
    0.396728515625,  # the stepped sine's lowest: two cycles per segment
    7.4005126953125,
    333.3333333,  # the third harmonic 1e-5 Hz below Nyquist: its sine column all but vanishes
])
def test_fundamentals_equal_a_direct_least_squares_fit(frequency_hz: float) -> None:
    fs, n = 2000.0, 1 << 15
    rng = np.random.default_rng(11)
    t = np.arange(n) / fs
    x = (2.5 + 0.004 * np.sin(2 * np.pi * frequency_hz * t + 0.7)
         + 4e-4 * np.sin(2 * np.pi * 2 * frequency_hz * t) + rng.normal(0.0, 1e-4, n))
    length, hop, count = frf.segment_layout(n, frequency_hz, fs)
    segments = frf._segments(x, length, hop, count)
    fitted = frf._fit_fundamentals(segments, frequency_hz, fs, frf.HARMONICS)
    direct = _direct_fundamentals(np.ascontiguousarray(segments), frequency_hz, fs,
                                  frf.HARMONICS)
    # both solve a problem of condition ≈ 1.4 (√2: Hann-weighted whole cycles) on a record
    # whose mean (2.5 V) is 600× the fundamental (4 mV): rounding of the mean's share,
    # ≈ 1e-16 × 600 ≈ 1e-13 of the fundamental, with a 100× margin
    assert np.max(np.abs(fitted / direct - 1.0)) < 1e-11
    assert np.abs(fitted) == pytest.approx(0.004, rel=0.05)  # and it is the fundamental


@pytest.mark.parametrize("harmonics", [1, frf.HARMONICS])
def test_the_design_is_the_stacked_columns_bit_for_bit(harmonics: int) -> None:
    """The columns written in place are column_stack's of the same cosines and sines."""
    angles = np.outer(2.0 * np.pi * 0.992 / 2000.0 * np.arange(16_129), np.arange(1, harmonics + 1))
    stacked = np.column_stack([np.ones(angles.shape[0]), np.cos(angles), np.sin(angles)])
    np.testing.assert_array_equal(frf._design(angles), stacked)
