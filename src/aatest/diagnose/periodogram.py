"""Spectral sums the diagnose searches evaluate many times, computed without big temporaries.

Two quantities are evaluated inside searches (a grid of frequencies, a bounded scalar search)
on long records, where the obvious one-liners cost seconds and gigabytes:

* the classical Lomb–Scargle periodogram over a grid of angular frequencies —
  ``scipy.signal.lombscargle`` (SciPy ≥ 1.15) builds several (samples × frequencies) arrays at
  once, 2 GB for a 16-step dataset; here the frequencies are swept by a complex rotation, one
  sample-length vector at a time;
* the discrete Fourier sum Σ x_k·exp(−iωt_k) at one frequency — on a uniform grid the phasor
  factorises over a (blocks × block) reshape, so √n complex exponentials replace n.

Both return what the direct formula returns, to rounding.
"""

from __future__ import annotations

import numpy as np

#: frequencies swept by rotation before the phasor is recomputed exactly (bounds round-off)
_REANCHOR = 64
#: relative deviation from a uniform grid below which the factorised DFT is used
_UNIFORM_RTOL = 1e-12
#: shortest record the factorised DFT is used for
_MIN_FACTORISED = 16


def lomb_scargle_power(x: np.ndarray, y: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """Classical Lomb–Scargle power of ``y`` sampled at ``x``, at angular frequencies ``omega``.

    Equal to ``scipy.signal.lombscargle(x, y, omega)`` (``normalize=False``, no floating mean):
    half the squared norm of the projection of ``y`` on {cos ωx, sin ωx}, in y-units². ``x`` is
    in any unit u (seconds, degrees), ``omega`` in rad/u. Memory is O(len(x)); an evenly spaced
    ``omega`` is swept by complex rotation (exact phasors every 64 frequencies).
    """
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64).astype(complex)  # real @ complex has no fast path
    omega = np.asarray(omega, dtype=np.float64)
    n = float(x.size)
    out = np.empty(omega.size)
    step = np.diff(omega)
    even = omega.size > 1 and bool(np.allclose(step, step[0], rtol=1e-9, atol=0.0))
    rot = np.exp(1j * step[0] * x) if even else None
    z = np.empty(0, dtype=complex)
    for k, w in enumerate(omega):
        if rot is None or k % _REANCHOR == 0:
            z = np.exp(1j * w * x)
        else:
            z *= rot
        b = y @ z  # Σ y cos ωx + i Σ y sin ωx
        z2 = z @ z  # Σ exp(2iωx) = Σ cos 2ωx + i Σ sin 2ωx
        cc, ss, cs = 0.5 * (n + z2.real), 0.5 * (n - z2.real), 0.5 * z2.imag
        det = cc * ss - cs * cs
        if det <= 0.0:
            out[k] = 0.0
            continue
        yc, ys = b.real, b.imag
        out[k] = 0.5 * (ss * yc * yc - 2.0 * cs * yc * ys + cc * ys * ys) / det
    return out


def lomb_scargle_at(time_s: np.ndarray, y: np.ndarray, f_hz: float) -> float:
    """:func:`lomb_scargle_power` of ``y`` at the one frequency ``f_hz`` (ω = 2πf).

    The two sums it needs, Σ y·exp(iωt) and Σ exp(2iωt), are :func:`dft_at` sums (conjugated),
    so on a uniform grid about 2√n complex exponentials are evaluated instead of n: a line
    search calls this a few hundred times on 2^14-sample steps.
    """
    t = np.asarray(time_s, dtype=np.float64)
    uniform = is_uniform(t)
    b = dft_at(y, t, f_hz, uniform).conjugate()  # Σ y cos ωt + i Σ y sin ωt
    z2 = dft_at(np.ones(t.size), t, 2.0 * f_hz, uniform).conjugate()  # Σ exp(2iωt)
    n = float(t.size)
    cc, ss, cs = 0.5 * (n + z2.real), 0.5 * (n - z2.real), 0.5 * z2.imag
    det = cc * ss - cs * cs
    if det <= 0.0:
        return 0.0
    yc, ys = b.real, b.imag
    return float(0.5 * (ss * yc * yc - 2.0 * cs * yc * ys + cc * ys * ys) / det)


def is_uniform(time_s: np.ndarray) -> bool:
    """Whether ``time_s`` is t0 + k·dt to rounding."""
    n = time_s.size
    if n < _MIN_FACTORISED:
        return False
    dt = (time_s[-1] - time_s[0]) / (n - 1)
    tol = _UNIFORM_RTOL * max(abs(time_s[-1]), abs(time_s[0]), dt)
    return bool(np.max(np.abs(time_s - time_s[0] - dt * np.arange(n))) <= tol)


def dft_at(values: np.ndarray, time_s: np.ndarray, f_hz: float,
           uniform: bool | None = None) -> complex:
    """Σ values_k · exp(−2πi·f·t_k) (V·1 for volts; units of ``values``).

    On a uniform grid t_k = t0 + k·dt the phasor factorises as exp(−iω(t0 + (mB + j)dt)) over a
    (m, j) reshape of the record, so only about 2√n exponentials are evaluated; otherwise the
    direct sum is used. ``uniform``: whether ``time_s`` is uniform (:func:`is_uniform`), when
    the caller knows (a scan of many frequencies on one grid checks it once); None: checked.
    """
    v = np.asarray(values, dtype=np.float64)
    t = np.asarray(time_s, dtype=np.float64)
    w = 2.0 * np.pi * float(f_hz)
    n = v.size
    if not (is_uniform(t) if uniform is None else uniform):
        return complex(v.astype(complex) @ np.exp(-1j * w * t))
    dt = (t[-1] - t[0]) / (n - 1)
    block = max(1, int(np.sqrt(n)))
    rows, rest = divmod(n, block)
    inner = np.exp(-1j * w * dt * np.arange(block))
    outer = np.exp(-1j * w * (t[0] + dt * block * np.arange(rows)))
    # real @ complex has no BLAS path in NumPy: multiply the real and imaginary parts apart
    head = v[: rows * block].reshape(rows, block)
    total = outer @ (head @ inner.real + 1j * (head @ inner.imag))
    if rest:
        total += v[rows * block:].astype(complex) @ np.exp(-1j * w * t[rows * block:])
    return complex(total)
