"""A calibration interval from a unit's own as-found/as-left variables data (Castrup's method).

H. Castrup, "Calibration Intervals from Variables Data", NCSL International Workshop and
Symposium, 2005. The value of a calibrated quantity is modelled as normally distributed about
a drift curve ``y(t)`` of the time ``t`` elapsed since its last calibration: the *deviation*
``y = as-found − as-left`` of every calibration interval the unit has been through is regressed
on the elapsed time with a polynomial through the origin (no drift at ``t = 0``),
``y(t) = b₁t + … + bₘtᵐ``. The scatter about the curve (``s²``, with ``n − m`` degrees of
freedom), the covariance of the coefficients and the uncertainty ``u₀`` of the as-left value
make up the prediction uncertainty ``u(t)² = u₀² + s² + g(t)ᵀ C g(t)`` with
``g(t) = (t, …, tᵐ)``. The probability that the quantity is still inside its tolerance limits
``[L₁, L₂]`` at the end of a period ``t`` (the end-of-period reliability) is::

    R(t) = F_ν((L₂ − x_left − y(t)) / u(t)) − F_ν((L₁ − x_left − y(t)) / u(t))

with ``F_ν`` Student's t distribution of ``ν = n − m`` degrees of freedom (the prediction
interval of a regression). The recommended interval is the first ``t`` at which ``R`` falls to
the lab's reliability target.

The regression is weighted when every deviation states its uncertainty: the weights
``wᵢ = ū² / u(yᵢ)²`` are relative (normalised to a mean variance of one), so ``s²`` is still
the scatter of a typical interval, estimated from the data as in Castrup's unweighted case.
An aatest certificate states no adjustment unless ``metadata.adjustment`` says so, so the
as-left value of a calibration is its certified value (:func:`as_left_value`).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import optimize, stats

from aatest.engine.errors import AnalysisError
from aatest.metrology.uncertainty.gum import K_COVERAGE
from aatest.records.models import CalibrationRecord

DAYS_PER_MONTH = 365.25 / 12.0
#: how far ahead an interval is looked for (beyond it the drift data say nothing useful)
HORIZON_DAYS = 20 * 365.25
#: points of the first scan for the crossing (then refined by Brent's method)
_SCAN_POINTS = 4001
#: the root is refined to a thousandth of a day: far below any interval's meaning
_XTOL_DAYS = 1e-3


@dataclass(frozen=True)
class DriftSample:
    """One calibration interval of a unit: how far the quantity moved, and in how long."""

    elapsed_days: float
    deviation: float
    #: standard uncertainty of the deviation (as-found and as-left), None if either is unstated
    u_deviation: float | None


@dataclass(frozen=True)
class DriftFit:
    """The regression of the deviation on the elapsed time (Castrup eqs. 5-10)."""

    coefficients: np.ndarray
    covariance: np.ndarray
    s: float
    dof: int
    weighted: bool
    samples: tuple[DriftSample, ...]

    @property
    def degree(self) -> int:
        return len(self.coefficients)

    def _basis(self, days: np.ndarray) -> np.ndarray:
        return np.power.outer(np.asarray(days, dtype=float), np.arange(1, self.degree + 1))

    def deviation(self, days: np.ndarray | float) -> np.ndarray:
        """Predicted deviation from the as-left value after ``days``."""
        return self._basis(np.atleast_1d(days)) @ self.coefficients

    def u_prediction(self, days: np.ndarray | float) -> np.ndarray:
        """Standard uncertainty of a new deviation after ``days``: ``√(s² + gᵀCg)``."""
        g = self._basis(np.atleast_1d(days))
        return np.sqrt(self.s**2 + np.einsum("ij,jk,ik->i", g, self.covariance, g))


def standard_uncertainty(expanded: float | None) -> float | None:
    """``U / k`` with the engine's ``k = 2``: a larger stated ``k`` (few degrees of freedom)
    would give a smaller ``u``, so this errs towards shorter intervals."""
    return None if expanded is None else expanded / K_COVERAGE


def as_left_value(record: CalibrationRecord, name: str, adjusted: dict[str, float] | None
                  ) -> float:
    """What the unit was left at: the certified value unless an adjustment states another."""
    if adjusted and name in adjusted:
        return float(adjusted[name])
    return record.quantities[name].value


def drift_samples(records: Sequence[CalibrationRecord], name: str,
                  adjustments: dict[int, dict[str, float]] | None = None
                  ) -> list[DriftSample]:
    """The deviations of ``name`` between consecutive calibrations of one unit, oldest first.

    ``adjustments`` maps a record id to the as-left values its adjustment stated.
    """
    rows = [r for r in records if name in r.quantities]
    samples = []
    for left, found in itertools.pairwise(rows):
        days = (found.calibrated_utc - left.calibrated_utc).total_seconds() / 86400.0
        if days <= 0:
            continue  # two calibrations at once say nothing about drift
        x_left = as_left_value(left, name, (adjustments or {}).get(left.id))
        u_left = standard_uncertainty(left.quantities[name].expanded_uncertainty)
        u_found = standard_uncertainty(found.quantities[name].expanded_uncertainty)
        u = None if u_left is None or u_found is None else math.hypot(u_left, u_found)
        samples.append(DriftSample(days, found.quantities[name].value - x_left, u))
    return samples


def fit_deviation(samples: Sequence[DriftSample], degree: int = 1) -> DriftFit:
    """Least squares of the deviation on ``t, …, tᵐ`` (through the origin), weighted by the
    relative inverse variances when every sample states a non-zero uncertainty."""
    if degree < 1:
        raise AnalysisError(f"drift polynomial degree {degree}: must be at least 1")
    if len(samples) <= degree:
        raise AnalysisError(f"{len(samples)} calibration interval(s): a degree-{degree} drift "
                            f"needs at least {degree + 1} to estimate its scatter")
    t = np.array([s.elapsed_days for s in samples])
    y = np.array([s.deviation for s in samples])
    us = [s.u_deviation for s in samples]
    weighted = all(u is not None and u > 0 for u in us)
    variance = np.array(us, dtype=float) ** 2 if weighted else np.ones_like(t)
    w = variance.mean() / variance
    basis = np.power.outer(t, np.arange(1, degree + 1))
    normal = basis.T @ (w[:, None] * basis)
    coefficients = np.linalg.solve(normal, basis.T @ (w * y))
    residual = y - basis @ coefficients
    dof = len(t) - degree
    s2 = float(np.sum(w * residual**2) / dof)
    return DriftFit(coefficients, s2 * np.linalg.inv(normal), math.sqrt(s2), dof, weighted,
                    tuple(samples))


@dataclass(frozen=True)
class IntervalRecommendation:
    """The interval at which the end-of-period reliability falls to ``target``."""

    fit: DriftFit
    x_left: float
    u_left: float
    limits: tuple[float, float]
    target: float
    #: None: the reliability stays above the target for :data:`HORIZON_DAYS`
    days: float | None

    def reliability(self, days: np.ndarray | float) -> np.ndarray:
        """End-of-period in-tolerance probability ``R(t)`` after ``days``."""
        days = np.atleast_1d(np.asarray(days, dtype=float))
        mean = self.x_left + self.fit.deviation(days)
        scale = np.sqrt(self.u_left**2 + self.fit.u_prediction(days) ** 2)
        low, high = self.limits
        dist = stats.t(self.fit.dof)
        return np.asarray(dist.cdf((high - mean) / scale) - dist.cdf((low - mean) / scale))

    @property
    def months(self) -> float | None:
        return None if self.days is None else self.days / DAYS_PER_MONTH


def recommend_interval(fit: DriftFit, x_left: float, u_left: float,
                       limits: tuple[float, float], target: float) -> IntervalRecommendation:
    """The first elapsed time at which ``R(t)`` reaches ``target`` (0 when it starts below).

    ``R`` need not fall monotonically (a drift towards the middle of the band first raises
    it), so the whole horizon is scanned for the first crossing, which Brent's method then
    refines.
    """
    if not 0.0 < target < 1.0:
        raise AnalysisError(f"reliability target {target}: must lie strictly between 0 and 1")
    low, high = limits
    if not low < high:
        raise AnalysisError(f"tolerance limits {limits}: the lower must lie below the upper")
    found = IntervalRecommendation(fit, x_left, u_left, limits, target, None)
    grid = np.linspace(0.0, HORIZON_DAYS, _SCAN_POINTS)
    below = found.reliability(grid) < target
    if below[0]:
        return IntervalRecommendation(fit, x_left, u_left, limits, target, 0.0)
    if not below.any():
        return found
    i = int(np.argmax(below))
    days = optimize.brentq(lambda d: float(found.reliability(d)[0]) - target,
                           grid[i - 1], grid[i], xtol=_XTOL_DAYS)
    return IntervalRecommendation(fit, x_left, u_left, limits, target, float(days))
