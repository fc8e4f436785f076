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

from aatest.plugins.analysis.tfest import _to_z
from aatest.plugins.analysis.transfer_function import (
    TransferFunctionOptions,
    _candidate,
    dc_gain,
    estimate,
    split_points,
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
