"""The transfer-function fit's shortcuts give the very numbers of the routines they replace.

Why exact equality here: each shortcut performs the same floating-point operations in the
same order as the library call it stands for (NumPy's ``Polynomial`` operators,
python-control's ``dcgain``, a second fit of the same structure), so results.json of a run
must not move by one bit; a tolerance would hide a reordering.
"""

from __future__ import annotations

import numpy as np
import pytest
from numpy.polynomial import Polynomial
from scipy import optimize

from aatest.plugins.analysis.tf_models import (
    TransferFunctionOptions,
    _candidate,
    dc_gain,
    estimate,
    split_points,
)
from aatest.plugins.analysis.tfest import (
    _SK_ITERATIONS,
    _polyval,
    _refine,
    _sk_fit,
    _to_z,
    _w_of,
)

FS = 2000.0
F_HZ = np.linspace(0.5, 28.0, 24)


def _to_z_by_polynomial(p_w: np.ndarray, c: float) -> np.ndarray:
    """The former construction: Σ coef·Polynomial([−1/c, 1/c])**i."""
    zm1 = Polynomial([-1.0 / c, 1.0 / c])
    out = Polynomial([0.0])
    for i, coef in enumerate(p_w):
        out = out + coef * zm1**i
    return np.asarray(out.coef)


def test_to_z_equals_polynomial_operators() -> None:
    rng = np.random.default_rng(11)
    for _ in range(2000):
        size = int(rng.integers(1, 7))
        p_w = rng.normal(size=size) * 10.0 ** rng.uniform(-6, 6, size=size)
        if rng.random() < 0.2:  # exact zeros: Polynomial trims trailing ones
            p_w[rng.integers(0, size)] = 0.0
        c = 10.0 ** rng.uniform(-4, 1)
        expected, got = _to_z_by_polynomial(p_w, c), _to_z(p_w, c)
        assert got.shape == expected.shape
        assert np.array_equal(got, expected)


def test_dc_gain_equals_python_control() -> None:
    control = pytest.importorskip("control")
    rng = np.random.default_rng(12)
    for _ in range(500):
        num = rng.normal(size=int(rng.integers(1, 5))) * 10.0 ** rng.uniform(-5, 5)
        den = rng.normal(size=int(rng.integers(1, 7))) * 10.0 ** rng.uniform(-5, 5)
        den[0] = den[0] or 1.0
        expected = float(np.real(control.TransferFunction(num, den).dcgain()))
        assert dc_gain(num, den) == expected
    assert dc_gain(np.array([1.0]), np.array([1.0, 4.0])) == 0.25


def _second_order_frf() -> np.ndarray:
    s = 2j * np.pi * F_HZ
    wn = 2 * np.pi * 40.0
    return 0.004 * wn**2 / (s**2 + 1.4 * wn * s + wn**2) * np.exp(-s * 3 / FS)


def test_scan_reuses_the_cross_correlation_fit() -> None:
    """The scanned delay equal to the accepted cross-correlation delay is the xcorr row
    (only its source differs), and its model is what a fresh fit gives."""
    h = _second_order_frf()
    xcorr = {"delay_samples": 3, "accepted": True, "strength": 0.99, "delay_s": 3 / FS}
    _model, rows, _k = estimate(F_HZ, h, 1 / FS, xcorr)
    for n, m in ((1, 0), (2, 1)):
        scanned = [r for r in rows if (r["n"], r["m"], r["delay_source"]) == (n, m, "scan")
                   and r["delay_samples"] == 3]
        xc = [r for r in rows if (r["n"], r["m"], r["delay_source"]) == (n, m, "xcorr")]
        assert len(scanned) == 1 and len(xc) == 1
        assert {**xc[0], "delay_source": "scan"} == scanned[0]
        assert list(scanned[0]) == list(xc[0])  # the same key order in results.json
        split = split_points(F_HZ, TransferFunctionOptions())
        _fresh, row = _candidate(F_HZ, h, n, m, 3, "scan", 1 / FS, split)
        assert row == scanned[0]  # a fit of its own gives the same row


def _sk_every_iteration(w: np.ndarray, g: np.ndarray, n: int, m: int
                        ) -> tuple[np.ndarray, np.ndarray]:
    """The Sanathanan–Koerner loop run to its last iteration (the former routine)."""
    weight = np.ones(w.size)
    pb, pa = np.zeros(m + 1), np.ones(1)
    basis = np.column_stack([w**i for i in range(m + 1)] + [-g * w**i for i in range(1, n + 1)])
    for _ in range(_SK_ITERATIONS if n else 1):
        design = basis / weight[:, None]
        rhs = g / weight
        a_real = np.vstack([design.real, design.imag])
        sol, *_ = np.linalg.lstsq(a_real, np.concatenate([rhs.real, rhs.imag]), rcond=None)
        pb, pa = sol[:m + 1], np.concatenate([[1.0], sol[m + 1:]])
        weight = np.abs(_polyval(w, pa))
    return pb, pa


def test_sk_cycle_shortcut_equals_every_iteration(monkeypatch: pytest.MonkeyPatch) -> None:
    """Taking the last iteration's solution from a repeating cycle gives its very bits, on
    structures that repeat early and on those that never do."""
    solves: list[int] = []
    lstsq = np.linalg.lstsq
    monkeypatch.setattr(np.linalg, "lstsq", lambda *a, **k: solves.append(1) or lstsq(*a, **k))
    early = 0
    dt = 1 / FS
    w0 = 2 * np.pi * F_HZ.max()
    w = _w_of(F_HZ, dt, w0)
    z = 1.0 + w * w0 * dt
    rng = np.random.default_rng(13)
    h = _second_order_frf() * (1 + 1e-3 * rng.normal(size=F_HZ.size))
    for n in range(4):
        for m in range(n + 1):
            for d in (0, 1, 3, 7):
                g = h * z**d * z ** (-(n - m))
                expected = _sk_every_iteration(w, g, n, m)
                solves.clear()
                got = _sk_fit(w, g, n, m)
                early += len(solves) < _SK_ITERATIONS and n > 0
                assert all(np.array_equal(e, x) for e, x in zip(expected, got, strict=True))
    assert early >= 3  # the shortcut is exercised (5 of these 36 fits repeat early)


def _refine_unkept(w: np.ndarray, g: np.ndarray, pb: np.ndarray, pa: np.ndarray
                   ) -> np.ndarray:
    """The output-error refinement evaluating every residual and Jacobian afresh."""
    m1, scale = pb.size, 1.0 / np.abs(g)
    powers = w[:, None] ** np.arange(max(m1, pa.size))

    def parts(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return _polyval(w, theta[:m1]), _polyval(w, np.concatenate([[1.0], theta[m1:]]))

    def residual(theta: np.ndarray) -> np.ndarray:
        num, den = parts(theta)
        e = (g - num / den) * scale
        return np.concatenate([e.real, e.imag])

    def jacobian(theta: np.ndarray) -> np.ndarray:
        num, den = parts(theta)
        inv = scale / den
        jac = np.concatenate([-powers[:, :m1] * inv[:, None],
                              powers[:, 1:pa.size] * (num * inv / den)[:, None]], axis=1)
        return np.concatenate([jac.real, jac.imag])

    theta0 = np.concatenate([pb, pa[1:]])
    return np.asarray(optimize.leastsq(residual, theta0, Dfun=jacobian, full_output=True,
                                       ftol=1e-8, xtol=1e-8, gtol=1e-8,
                                       maxfev=200 * theta0.size, factor=100.0, diag=None)[0])


def test_kept_evaluations_give_the_same_refinement() -> None:
    """Reusing the last point's residual and Jacobian changes no iterate: the same bits."""
    dt = 1 / FS
    w0 = 2 * np.pi * F_HZ.max()
    w = _w_of(F_HZ, dt, w0)
    z = 1.0 + w * w0 * dt
    h = _second_order_frf() * (1 + 1e-3 * np.random.default_rng(14).normal(size=F_HZ.size))
    for n, m, d in ((1, 0, 0), (2, 1, 3), (2, 2, 5), (3, 1, 0)):
        g = h * z**d * z ** (-(n - m))
        pb, pa = _sk_fit(w, g, n, m)
        got = np.concatenate(_refine(w, g, pb, pa))
        expected = _refine_unkept(w, g, pb, pa)
        assert np.array_equal(got, np.concatenate([expected[:m + 1], [1.0], expected[m + 1:]]))
