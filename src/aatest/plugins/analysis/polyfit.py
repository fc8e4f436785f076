"""Polynomial calibration models by QR least squares, with the statistics a lab signs.

Model (docs/method.md §4.3): y = Σ a_i·u^i, i = 0..p, u the sensor output (V, bias removed), y the
reference acceleration (°/s²). The design is built on u/u_max (so order 15 stays well
conditioned) and the coefficients are mapped back to physical units exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from aatest.numerics import TINY
from aatest.plugins.analysis._common import t95


@dataclass(frozen=True)
class PolyFit:
    """A fitted polynomial in physical units (ascending powers) with its statistics."""

    order: int
    coefficients: np.ndarray
    covariance: np.ndarray
    sse: float
    n: int
    sst: float

    @property
    def dof(self) -> int:
        return max(self.n - self.order - 1, 1)

    @property
    def rmse(self) -> float:
        """Root mean square residual with the degrees-of-freedom correction (fit units)."""
        return float(np.sqrt(self.sse / self.dof))

    @property
    def r2(self) -> float:
        return float(1.0 - self.sse / self.sst) if self.sst > 0 else 0.0

    @property
    def std_errors(self) -> np.ndarray:
        return np.sqrt(np.diag(self.covariance))

    @property
    def ci95(self) -> np.ndarray:
        """95 % bounds (Student t) per coefficient, shape (p+1, 2)."""
        half = t95(self.dof) * self.std_errors
        return np.column_stack([self.coefficients - half, self.coefficients + half])

    @property
    def correlation(self) -> np.ndarray:
        s = self.std_errors
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.nan_to_num(self.covariance / np.outer(s, s))

    def __call__(self, u: np.ndarray) -> np.ndarray:
        return np.polynomial.polynomial.polyval(u, self.coefficients)

    def summary(self) -> dict[str, object]:
        """JSON-able statistics of the fit."""
        return {
            "order": self.order,
            "coefficients": self.coefficients.tolist(),
            "std_uncertainty": self.std_errors.tolist(),
            "ci95": self.ci95.tolist(),
            "covariance": self.covariance.tolist(),
            "correlation": self.correlation.tolist(),
            "sse": self.sse,
            "rmse": self.rmse,
            "r2": self.r2,
            "n": self.n,
        }


def fit_polynomial(u: np.ndarray, y: np.ndarray, order: int, variance_inflation: float = 1.0
                   ) -> PolyFit:
    """Least-squares polynomial of ``order`` through (u, y) by a QR factorisation.

    Parameters
    ----------
    u, y
        Input and output samples (any units; coefficients come back in y/u^i).
    order
        Polynomial order p ≥ 0.
    variance_inflation
        Factor on the coefficient covariance for serially correlated residuals (e.g. the
        ratio of sample rate to twice the filter bandwidth after low-pass filtering).
    """
    u = np.asarray(u, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    scale = float(np.max(np.abs(u))) or 1.0
    design = np.vander(u / scale, order + 1, increasing=True)
    q, r = scipy.linalg.qr(design, mode="economic")
    c_scaled = scipy.linalg.solve_triangular(r, q.T @ y)
    residual = y - design @ c_scaled
    sse = float(residual @ residual)
    dof = max(u.size - order - 1, 1)
    r_inv = scipy.linalg.solve_triangular(r, np.eye(order + 1))
    cov_scaled = (r_inv @ r_inv.T) * sse / dof * variance_inflation
    to_phys = scale ** -np.arange(order + 1, dtype=np.float64)
    return PolyFit(order=order, coefficients=c_scaled * to_phys,
                   covariance=cov_scaled * np.outer(to_phys, to_phys), sse=sse, n=int(u.size),
                   sst=float(np.sum((y - y.mean()) ** 2)))


def naic(v: float, n_params: int, n: int) -> float:
    """Normalised Akaike criterion, MATLAB's definition: log V + 2·n_p/N."""
    return float(np.log(v) + 2.0 * n_params / n)


def fpe(v: float, n_params: int, n: int) -> float:
    """Akaike's final prediction error, MATLAB's definition: V·(1 + n_p/N)/(1 − n_p/N)."""
    return float(v * (1.0 + n_params / n) / (1.0 - n_params / n))


def fit_percent(y: np.ndarray, y_hat: np.ndarray) -> float:
    """Normalised-RMSE fit, MATLAB's definition: 100·(1 − ‖y − ŷ‖/‖y − ȳ‖) (complex allowed)."""
    y = np.asarray(y)
    return float(100.0 * (1.0 - np.linalg.norm(y - y_hat) / np.linalg.norm(y - y.mean())))


def cross_validate(u: np.ndarray, y: np.ndarray, max_order: int = 15, random_splits: int = 3,
                   seed: int = 0, id_fraction: float = 0.25) -> dict[str, np.ndarray]:
    """Orders 0..max_order on a fixed first-25 % split and ``random_splits`` random ones.

    One QR per split serves every order: the leading k columns of Q and R of the increasing
    Vandermonde matrix are the QR factors of the order-(k−1) design.
    Returns per order (rows) and split (columns): validation RMSE and identification nAIC.
    """
    n = u.size
    n_id = int(id_fraction * n)
    rng = np.random.default_rng(seed)
    splits = [np.arange(n)] + [rng.permutation(n) for _ in range(random_splits)]
    rmse_val = np.zeros((max_order + 1, len(splits)))
    aic = np.zeros_like(rmse_val)
    scale = float(np.max(np.abs(u))) or 1.0
    for j, perm in enumerate(splits):
        ident, valid = perm[:n_id], perm[n_id:]
        q, r = scipy.linalg.qr(np.vander(u[ident] / scale, max_order + 1, increasing=True),
                               mode="economic")
        qty = q.T @ y[ident]
        design_val = np.vander(u[valid] / scale, max_order + 1, increasing=True)
        for p in range(max_order + 1):
            coef = scipy.linalg.solve_triangular(r[:p + 1, :p + 1], qty[:p + 1])
            rmse_val[p, j] = np.sqrt(np.mean((y[valid] - design_val[:, :p + 1] @ coef) ** 2))
            sse = max(float(y[ident] @ y[ident] - qty[:p + 1] @ qty[:p + 1]), TINY)
            aic[p, j] = naic(sse / n_id, p + 1, n_id)
    return {"rmse_validation": rmse_val, "naic": aic}


def choose_order(table: dict[str, np.ndarray], rel_tol: float = 0.05, min_order: int = 1,
                 abs_tol: float = 0.0) -> int:
    """Lowest order whose criteria are not meaningfully worse than the best (docs/method.md §4.3).

    "Meaningfully" = mean validation RMSE above the best by more than ``rel_tol`` (5 %) *and*
    by more than ``abs_tol`` (the sensor's resolution: no one can use a smaller gain), with
    the equivalent allowance on nAIC (2·log of the RMSE ratio). Residuals of filtered records
    are serially correlated and the sensor's dynamics and hysteresis leave small systematic
    residuals, so every added term "helps" a little; this keeps real curvature (a cubic) and
    drops the rest.
    """
    rmse = table["rmse_validation"].mean(axis=1)
    aic = table["naic"].mean(axis=1)
    ratio = max(1.0 + rel_tol, 1.0 + abs_tol / max(float(rmse.min()), TINY))
    ok = (rmse <= rmse.min() * ratio) & (aic <= aic.min() + 2.0 * np.log(ratio) + 1e-9)
    ok[:min_order] = False
    return int(np.flatnonzero(ok)[0]) if ok.any() else int(np.argmin(rmse))


def nonlinearity(fit: PolyFit, u_min: float, u_max: float, points: int = 512) -> float:
    """Curvature of the fitted curve f against its own best straight line over the input range,
    sqrt(mean((f − ĝ)²)) (output units): 0 by construction at order ≤ 1. Not the study's L
    (:func:`linearity_l`), which compares the model with the record's ideal line."""
    grid = np.linspace(u_min, u_max, points)
    f = fit(grid)
    g = np.polynomial.polynomial.polyval(grid, np.polynomial.polynomial.polyfit(grid, f, 1))
    return float(np.sqrt(np.mean((f - g) ** 2)))


def linearity_l(fit: PolyFit, u: np.ndarray, ideal: np.ndarray) -> float:
    """The study's (non)linearity L (Eq. 3.36): sqrt(mean((f(u_k) − g(u_k))²)) over the
    record's inputs u_k (output units), f the fitted model and g the ideal line
    ``ideal`` = (intercept, slope) — in the study g = 250.02·u − 0.319 (°/s²)/V, the straight
    line against the table's own acceleration estimate."""
    g = np.polynomial.polynomial.polyval(u, ideal)
    return float(np.sqrt(np.mean((fit(u) - g) ** 2)))
