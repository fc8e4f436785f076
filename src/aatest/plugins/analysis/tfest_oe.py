"""Time-domain (output-error) estimation of a discrete transfer function from input/output records.

MATLAB's ``tfest`` on time-domain data minimises the simulation error ‖y − G(q)·u‖² over the
estimation records. With the table's *noisy* acceleration estimate as input u, that is not the
fit to the FRF points at the excitation frequencies (:func:`aatest.plugins.analysis.tfest.
fit_discrete_tf`): the noise in u, spread over every frequency, also costs, so the estimate
trades the fit at the excitation against the model's gain where only noise is. A model that must
lead its input (a fixed delay longer than the lag in the data) pays for that lead in amplified
noise — which is why the study's models with a 28-sample delay fit 5–6 points worse.

By Parseval the error of every record over whole cycles is, per DFT bin k,
Σ_r |Y_r(k) − G(k)·U_r(k)|² = S_uu(k)·|G(k) − Ĝ(k)|² + (a term free of G), with
S_uu = Σ_r |U_r|² and Ĝ = Σ_r Y_r·U_r* / S_uu: one weighted residual per bin, whatever the number
of records. The records are treated as periodic (the study's are whole cycles of their sine).
The denominator is parametrised by its reflection coefficients k_i = tanh(θ_i) (|k_i| < 1 ⇔
every pole inside the unit circle, the Schur–Cohn condition), so the fit cannot leave the
stable models — a frequency-domain cost alone would happily fit phase lead with an unstable
pole that a simulation then diverges on. ``scipy.optimize.least_squares`` does the search.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy import optimize

from aatest.plugins.analysis.tfest import DiscreteTf

#: reflection coefficients are kept this far inside ±1 at the start (arctanh stays finite)
_K_MAX = 0.999
#: the search's budget: function evaluations per parameter (a good start converges in far fewer)
_MAX_NFEV_PER_PARAMETER = 30
#: default start poles (real, inside the unit circle) when no stable start model is given
_START_POLES = (0.9, 0.8, 0.7, 0.6, 0.5, 0.4, 0.3, 0.2)


def rc_to_poly(k: np.ndarray) -> np.ndarray:
    """Monic denominator [1, a1..an] from reflection coefficients (Levinson step-up)."""
    a = np.ones(1)
    for ki in np.asarray(k, dtype=np.float64):
        ext = np.concatenate([a, [0.0]])
        a = ext + ki * ext[::-1]
    return a


def poly_to_rc(a: np.ndarray) -> np.ndarray:
    """Reflection coefficients of a stable monic [1, a1..an] (Levinson step-down)."""
    a = np.asarray(a, dtype=np.float64)
    k = np.zeros(a.size - 1)
    for i in range(a.size - 1, 0, -1):
        k[i - 1] = a[i]
        a = (a[:i] - k[i - 1] * a[i:0:-1]) / (1.0 - k[i - 1] ** 2)
    return k


def record_spectra(records: Sequence[tuple[np.ndarray, np.ndarray]], dt: float
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(frequencies Hz, S_uu, Ĝ) of equal-length records, means removed (see the module)."""
    sizes = {np.asarray(u).size for u, _ in records}
    if len(sizes) != 1:
        raise ValueError(f"records of unequal length {sorted(sizes)}")
    u = np.array([np.asarray(u, np.float64) - np.mean(u) for u, _ in records])
    y = np.array([np.asarray(y, np.float64) - np.mean(y) for _, y in records])
    uf, yf = np.fft.rfft(u, axis=1), np.fft.rfft(y, axis=1)
    s_uu = np.sum(np.abs(uf) ** 2, axis=0)
    g_hat = np.sum(yf * uf.conj(), axis=0) / np.where(s_uu > 0, s_uu, 1.0)
    return np.fft.rfftfreq(u.shape[1], dt), s_uu, g_hat


def fit_discrete_tf_oe(records: Sequence[tuple[np.ndarray, np.ndarray]], n: int, m: int,
                       dt: float, delay_samples: int = 0, start: DiscreteTf | None = None
                       ) -> DiscreteTf:
    """Output-error fit of H(z) = z^(−d)·B(z⁻¹)/A(z⁻¹), n poles (stable), m ≤ n zeros.

    ``start`` (same structure, stable) seeds the search; otherwise real poles at 0.9, 0.8, …
    with the least-squares static gain.
    """
    if m > n:
        raise ValueError(f"m = {m} zeros > n = {n} poles")
    f_hz, s_uu, g_hat = record_spectra(records, dt)
    zinv = np.exp(-2j * np.pi * f_hz * dt)
    shift = zinv**delay_samples
    weight = np.sqrt(s_uu / np.max(s_uu))
    powers = zinv[:, None] ** np.arange(n + 1)

    def unpack(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return theta[:m + 1], rc_to_poly(np.tanh(theta[m + 1:]))

    def residual(theta: np.ndarray) -> np.ndarray:
        num, den = unpack(theta)
        g = shift * (powers[:, :m + 1] @ num) / (powers @ den)
        e = weight * (g_hat - g)
        return np.concatenate([e.real, e.imag])

    stable_start = start is not None and bool(np.all(np.abs(start.poles()) < 1.0))
    if start is not None and stable_start:
        num0, den0 = np.asarray(start.num, np.float64), np.asarray(start.den, np.float64)
    else:
        den0 = np.asarray(np.poly(_START_POLES[:n]) if n else np.ones(1), dtype=np.float64)
        gain = float(np.sum(weight**2 * (g_hat * shift.conj()).real) / np.sum(weight**2))
        num0 = np.zeros(m + 1)
        num0[0] = gain * float(np.sum(den0))
    k0 = np.clip(poly_to_rc(den0), -_K_MAX, _K_MAX)
    theta0 = np.concatenate([num0, np.arctanh(k0)])
    sol = optimize.least_squares(residual, theta0, method="trf", x_scale="jac",
                                max_nfev=_MAX_NFEV_PER_PARAMETER * theta0.size)
    num, den = unpack(sol.x)
    return DiscreteTf(num=num, den=den, delay_samples=delay_samples, dt=dt)
