"""Fast vectorised sin/cos (single-precision accuracy) and Gaussian noise for the twin.

Why: on this machine NumPy's float64 ``sin``/``cos`` and ``Generator.standard_normal`` run at
≈15 ns/sample (scalar libm, ziggurat) while float32 ``sin``/``cos`` and float64 add/log/sqrt are
SIMD-vectorised (< 1 ns/sample); the twin needs ~10 such passes over 2^17 samples per step.
``sincos32`` reduces the argument exactly in float64 to [−π, π] and evaluates in float32:
absolute error < 3e-7. Use it only where that is far below what matters — ripple terms of
≈1″, projections of small outer-axis terms, gravity (1e-7 g), noise — never for the main
excitation (the sine profile uses exact phasors, see :mod:`grid`).
"""

from __future__ import annotations

import numpy as np

_TWO_PI = 2.0 * np.pi


def sincos32(x: np.ndarray, dtype: type = np.float64) -> tuple[np.ndarray, np.ndarray]:
    """(sin x, cos x), absolute error < 3e-7 (radians in); ``dtype`` of the result."""
    x = np.asarray(x, dtype=np.float64)
    # x − 2π·rint(x/2π), in place (the same float64 operations without three temporaries)
    reduced = np.multiply(x, 1.0 / _TWO_PI)
    np.rint(reduced, out=reduced)
    reduced *= _TWO_PI
    np.subtract(x, reduced, out=reduced)
    r = reduced.astype(np.float32)
    return np.sin(r).astype(dtype, copy=False), np.cos(r).astype(dtype, copy=False)


def standard_normal(rng: np.random.Generator, n: int) -> np.ndarray:
    """n independent N(0, 1) samples by the exact Box–Muller transform of ``rng``'s uniforms.

    Single-precision trigonometry limits the relative precision of each sample to ~3e-7,
    irrelevant for noise; the distribution and independence are those of Box–Muller.
    """
    half = (n + 1) // 2
    u = rng.random(2 * half)
    # every stage in place in the uniforms' own buffer: radius in the first half, the angle
    # in the second, then the products written back over them (the same float64 operations)
    radius = np.subtract(1.0, u[:half], out=u[:half])  # 1 − u ∈ (0, 1]: no log(0)
    np.log(radius, out=radius)
    radius *= -2.0
    np.sqrt(radius, out=radius)
    angle = u[half:]
    angle *= _TWO_PI
    # float32 sin/cos promote exactly to float64 inside the products
    s, c = sincos32(angle, np.float32)
    np.multiply(radius, s, out=angle)
    np.multiply(radius, c, out=radius)
    return u[:n]
