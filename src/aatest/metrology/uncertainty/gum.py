"""GUM (JCGM 100) propagation of uncertainty for final quantities, with a Monte Carlo check.

A :class:`Measurand` is a measurement model ``y = f(x_1, …, x_n)`` written once, against an
:class:`Ops` namespace, so the *same* model is evaluated by the GUM law of propagation (with
``uncertainties`` on the final quantities only — never on sample arrays) and by a JCGM 101
Monte Carlo propagation (numpy, seeded) that tests use to validate the linearisation.

Inputs are described by their distribution: ``normal`` (``spread`` = standard uncertainty),
``rectangular`` (``spread`` = half-width ``a``, u = a/√3) and ``cosine_error`` — the factor
cos ε − 1 of an axis tilt ε uniform in ±``spread`` rad, whose first-order sensitivity is zero;
GUM then takes its exact mean and standard deviation as the input estimate (JCGM 100 §5.1.2).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from uncertainties import ufloat, umath

from aatest.results.base import BudgetRow

Distribution = Literal["normal", "rectangular", "cosine_error"]
#: coverage factor for ≈95 % coverage of a normal output (the brief asks k = 2)
K_COVERAGE = 2.0
#: coverage probability of k = 2 for a normal output: P(|z| ≤ 2)
P_COVERAGE = math.erf(K_COVERAGE / math.sqrt(2.0))


@dataclass(frozen=True)
class Ops:
    """The functions a model may use, so one model runs on ufloats and on numpy arrays."""

    sin: Callable[[Any], Any]
    cos: Callable[[Any], Any]
    asin: Callable[[Any], Any]
    log10: Callable[[Any], Any]
    sqrt: Callable[[Any], Any]


UMATH_OPS = Ops(umath.sin, umath.cos, umath.asin, umath.log10, umath.sqrt)
NUMPY_OPS = Ops(np.sin, np.cos, np.arcsin, np.log10, np.sqrt)

#: below this half-width the cosine-error moments are taken from their series
_SERIES_BELOW_RAD = 1e-2

Model = Callable[[Ops, Mapping[str, Any]], Any]


@dataclass(frozen=True)
class Input:
    """One input quantity of a measurement model and the budget row it produces."""

    name: str
    label: str
    value: float
    spread: float
    distribution: Distribution = "normal"
    unit: str = ""
    note: str = ""
    kind: Literal["A", "B"] = "B"
    evaluated: bool = True
    dof: float = math.inf

    def mean(self) -> float:
        """Expectation of the input (for ``cosine_error``: E[cos ε] − 1 = sin a / a − 1)."""
        if self.distribution == "cosine_error":
            a = abs(self.spread)
            return math.sin(a) / a - 1.0 if a > 0 else 0.0
        return self.value

    def standard_uncertainty(self) -> float:
        """Standard deviation of the input's distribution, in the input's unit."""
        a = abs(self.spread)
        if self.distribution == "rectangular":
            return a / math.sqrt(3.0)
        if self.distribution == "cosine_error":
            if a < _SERIES_BELOW_RAD:  # series: the closed form below cancels catastrophically
                return a**2 / math.sqrt(45.0)
            second = 0.5 + math.sin(2 * a) / (4 * a)  # E[cos² ε]
            first = math.sin(a) / a
            return math.sqrt(max(second - first**2, 0.0))
        return a

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``n`` draws from the input's distribution (for the Monte Carlo propagation)."""
        a = abs(self.spread)
        if self.distribution == "rectangular":
            return self.value + rng.uniform(-a, a, n)
        if self.distribution == "cosine_error":
            return np.cos(rng.uniform(-a, a, n)) - 1.0
        return self.value + a * rng.standard_normal(n)


@dataclass(frozen=True)
class Measurand:
    """A named output quantity, its unit, its measurement model and its inputs."""

    name: str
    unit: str
    model: Model
    inputs: tuple[Input, ...]
    definition: str = ""


@dataclass(frozen=True)
class Evaluation:
    """Result of a GUM evaluation: y, u_c(y), U = k·u_c(y) and the budget (JCGM 100 §8)."""

    name: str
    unit: str
    value: float
    standard_uncertainty: float
    expanded_uncertainty: float
    k: float
    rows: tuple[BudgetRow, ...]
    coverage_probability: float = P_COVERAGE
    definition: str = ""

    def share_pct(self, row: BudgetRow) -> float:
        """A row's share of the combined variance, u_i(y)²/u_c(y)², in %."""
        u_c = self.standard_uncertainty
        return 100.0 * row.contribution**2 / u_c**2 if u_c > 0 else 0.0

    @property
    def relative_expanded(self) -> float | None:
        """U / |y| (dimensionless), or None for a zero estimate."""
        return self.expanded_uncertainty / abs(self.value) if self.value else None


def coverage_factor(combined_u: float, contributions: list[tuple[float, float]],
                    k_infinite: float = K_COVERAGE) -> float:
    """k (dimensionless) for the coverage probability of ``k_infinite`` at the effective
    degrees of freedom; ``combined_u`` (u_c) and the u_i(y) are in the quantity's unit.

    Welch–Satterthwaite (JCGM 100 G.4): ν_eff = u_c⁴ / Σ u_i⁴/ν_i over the contributions
    (u_i(y), ν_i) with finite ν_i; k = t-quantile at ν_eff (G.6.4). Infinite ν_eff gives
    ``k_infinite`` itself.

    The normal CDF and the t-quantile are the special functions ``scipy.stats``' ``norm.cdf``
    and ``t.ppf`` evaluate (``ndtr``, ``stdtrit``), called directly: the same values, without
    the distributions' argument checks (≈ 40 µs a call; a stepped sine evaluates 272 budgets).
    """
    from scipy.special import ndtr, stdtrit

    finite = sum(u**4 / dof for u, dof in contributions if math.isfinite(dof) and dof > 0)
    if combined_u <= 0 or finite <= 0:
        return k_infinite
    dof_eff = combined_u**4 / finite
    probability = 2.0 * float(ndtr(k_infinite)) - 1.0
    return float(max(k_infinite, float(stdtrit(dof_eff, 0.5 + probability / 2.0))))


def evaluate(measurand: Measurand, k: float = K_COVERAGE) -> Evaluation:
    """Propagate the inputs through the model by the GUM law (first order, independent inputs)."""
    variables: dict[str, Any] = {
        i.name: ufloat(i.mean(), i.standard_uncertainty(), tag=i.name)
        if i.standard_uncertainty() > 0 else i.mean()
        for i in measurand.inputs
    }
    y = measurand.model(UMATH_OPS, variables)
    derivatives = {var.tag: d for var, d in getattr(y, "derivatives", {}).items()}
    u_c = float(getattr(y, "std_dev", 0.0))
    k = coverage_factor(u_c, [(abs(float(derivatives.get(i.name, 0.0)))
                               * i.standard_uncertainty(), i.dof) for i in measurand.inputs], k)
    rows = []
    for item in measurand.inputs:
        c = float(derivatives.get(item.name, 0.0))
        u_x = item.standard_uncertainty()
        rows.append(BudgetRow(
            name=item.name, label=item.label, value=item.mean(), standard_uncertainty=u_x,
            unit=item.unit, distribution=item.distribution, sensitivity=c,
            contribution=abs(c) * u_x, basis=item.note, quantity=item.label, type=item.kind,
            evaluated=item.evaluated,
        ))
    return Evaluation(
        measurand.name, measurand.unit, float(getattr(y, "nominal_value", y) or 0.0), u_c,
        k * u_c, k,
        tuple(rows), definition=measurand.definition,
    )


@dataclass(frozen=True)
class MonteCarloResult:
    """Monte Carlo (JCGM 101) summary of the output distribution."""

    mean: float
    standard_uncertainty: float
    interval95: tuple[float, float]
    draws: int


def monte_carlo(measurand: Measurand, draws: int = 200_000, seed: int = 0) -> MonteCarloResult:
    """Propagate the input *distributions* through the same model with ``draws`` samples."""
    rng = np.random.default_rng(seed)
    samples = {i.name: i.sample(rng, draws) for i in measurand.inputs}
    y = np.asarray(measurand.model(NUMPY_OPS, samples), dtype=float)
    y = np.broadcast_to(y, (draws,))
    lo, hi = np.quantile(y, [0.025, 0.975])
    return MonteCarloResult(float(np.mean(y)), float(np.std(y, ddof=1)), (float(lo), float(hi)),
                            draws)
