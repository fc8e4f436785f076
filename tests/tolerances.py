"""How closely results computed on another machine must agree with a committed reference.

A committed reference (a ``results.json`` written by an earlier run, perhaps on another CPU) can
only be matched to the precision the computation itself determines: another CPU selects another
OpenBLAS kernel (``OPENBLAS_CORETYPE``) and other SIMD loops in numpy, so sums and products are
rounded in another order, and every step that amplifies rounding (an ill-conditioned solve, an
iterative optimiser's stopping point, a difference of nearly equal numbers) carries that into
the result. Each rule below names a class of results, the tolerance that follows from how that
class is computed, and why. Measured on one recording (``recording/data/streaming``) with
``OPENBLAS_CORETYPE`` = SkylakeX, Haswell, Zen, Sandybridge and Nehalem and 1 or 2 BLAS
threads, the largest deviations from the reference were: transfer-function candidates' ``V``
8.9e-5 relative, their ``fit_pct`` 2e-4 percentage points, second-order-fit uncertainties 6.4e-7
relative, the selected model's poles 7.1e-10 relative, the clock drift 1.4e-10 ppm, everything
else ≤ 4e-13 relative.

Shared by every test that compares numbers against a committed reference
(``from tolerances import mismatches``); :data:`REFERENCE_RULES` are those of the comparison
with the dict-based engine's references (``tests/results/test_results_reference.py``).
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

#: sums and DFTs over ≤ 2**17 float64 samples round to ≲ ε·log2(N) ≈ 4e-15 of the sum of
#: magnitudes; a mean of a near-zero-mean signal (a bias, an offset) has a condition number
#: Σ|x| / |Σx| of up to 1e4, which leaves ≈ 4e-11; 1e-9 keeps a factor 25 above that.
DEFAULT_REL = 1e-9


@dataclass(frozen=True)
class Rule:
    """A class of result leaves (regex on the JSON path) and how close they must agree."""

    pattern: str
    rel: float
    abs: float
    reason: str


RULES: tuple[Rule, ...] = (
    Rule(r"transfer_function\..*(candidates\[\d+\]\.|\.)(V|FPE)$", 1e-3, 0.0,
         "validation variance at the stopping point of a Levenberg–Marquardt refinement "
         "(scipy least_squares, ftol = xtol = 1e-8): over-parameterised candidates lie in flat "
         "valleys where the stopping point is set only to √ftol = 1e-4 of the parameters; "
         "the held-out variance moves by up to that; 10× margin"),
    Rule(r"transfer_function\..*(candidates\[\d+\]\.|\.)nAIC$", 0.0, 1e-3,
         "nAIC = ln V + 2p/N: an absolute error equal to V's relative one (1e-3, above)"),
    Rule(r"transfer_function\..*(candidates\[\d+\]\.|\.)fit_(id_)?pct$", 0.0, 0.1,
         "fit % = 100·(1 − ‖r‖/‖y − ȳ‖) moves by (100 − fit)·ΔV/(2V) ≤ 200 × 5e-4 = 0.1 "
         "percentage points for V's 1e-3 (above)"),
    Rule(r"transfer_function\..*second_order_delay\.", 1e-5, 0.0,
         "four well-determined parameters at the minimum of a trust-region fit finished by "
         "Gauss–Newton steps (set to rounding, not by the solver's path), their uncertainties "
         "from (JᵀJ)⁻¹ of the analytic Jacobian there (condition ≲ 1e3)"),
    Rule(r"transfer_function\.", 1e-6, 0.0,
         "the selected model's coefficients stop at the refinement's xtol = 1e-8; mapping the "
         "scaled w-polynomials to z (w = (z − 1)/(ω₀T)) amplifies by its condition ≲ 1e2"),
    Rule(r"drift(_spread)?_ppm$", 0.0, 1e-6,
         "drift = (slope − 1)·1e6 of a straight-line fit to edge times (condition ≈ 10 after "
         "centring): the slope is set to ≈ 1e-14, i.e. 1e-8 ppm absolute — a relative "
         "comparison of this difference of nearly equal numbers would be meaningless"),
)


#: results.json of the shipped procedures against the references the dict-based engine wrote
#: (tests/results/test_results_reference.py): the same machine class, but a changed code path
#: (typed records instead of dicts) may round in another order; paths have no leading dot
REFERENCE_RULES: tuple[Rule, ...] = (
    Rule(r"^analysis\.scale_factor\..*\.(fit|inverse|validation|coefficients|ci95|scale_ci95)",
         1e-3,
         1e-12, "high-order polynomial least squares, condition ~1e12: polynomial fits up to "
         "order 15 on a Vandermonde matrix (condition number ~1e12 even after centring): their "
         "higher coefficients, covariances and the statistics derived from them carry ~1e-4 "
         "of relative noise from the last bit of the solve; the scale factor's interval "
         "(scale_ci95) comes from the same covariance once the order is above 1"),
    Rule(r"^analysis\.transfer_function\.", 1e-5, 1e-12,
         "transfer-function least squares of lagged samples, condition ~1e8: ARX candidate "
         "models of order up to 6 (normal equations of lagged samples) and the metrics (nAIC, "
         "FPE, fit %) computed from their residuals"),
    Rule(r"^analysis\.drift\..*\.allan_fit", 1e-6, 1e-15,
         "Allan-term least squares: the Allan deviation fit solves for terms that are "
         "differences of nearly equal slopes"),
    Rule(r"^.*(correlation|residual|_rms_|rmse|sse)", 1e-7, 1e-14,
         "residuals and correlations: differences of nearly equal numbers (a correlation near "
         "±1 or a residual near 0): an absolute tolerance at the scale of its inputs' "
         "rounding"),
    Rule(r"^analysis\.scale_factor\..*\.nonlinearity_(dps2|pct_fr)$", 1e-9, 1e-9,
         "deviation of a fit from itself: rounding noise around zero (~1e-13 °/s²)"),
    Rule(r"^analysis\.sync\.drift_spread_ppm$", 1e-9, 1e-6,
         "the spread of per-step drifts: a difference of nearly equal fitted drifts (ppm), as "
         "the drift class of RULES"),
)


def tolerance(path: str, rules: tuple[Rule, ...] = RULES) -> Rule:
    """The first of ``rules`` whose pattern matches ``path``, else the default relative
    tolerance."""
    for rule in rules:
        if re.search(rule.pattern, path):
            return rule
    return Rule("", DEFAULT_REL, 0.0, "well-conditioned sums, means and DFT ratios")


def leaves(value: Any, path: str = "") -> Iterator[tuple[str, Any]]:
    """Every leaf of a JSON document with its path (``.analysis.sync.drift_ppm``, ``[3]``)."""
    if isinstance(value, dict):
        for key, item in value.items():
            yield from leaves(item, f"{path}.{key}")
    elif isinstance(value, list):
        for i, item in enumerate(value):
            yield from leaves(item, f"{path}[{i}]")
    else:
        yield path, value


def close(path: str, got: Any, want: Any) -> bool:
    """Whether one leaf agrees: floats within their rule, NaN with NaN, anything else equal."""
    if isinstance(got, float) and isinstance(want, float):
        if math.isnan(got) or math.isnan(want):
            return math.isnan(got) and math.isnan(want)
        rule = tolerance(path)
        return math.isclose(got, want, rel_tol=rule.rel, abs_tol=rule.abs)
    return bool(got == want)


def mismatches(got: dict[str, Any], want: dict[str, Any]) -> list[str]:
    """Paths (with both values) where ``got`` differs from ``want`` beyond its tolerance."""
    return [f"{path}: {got[path]!r} vs {want[path]!r} ({tolerance(path).reason})"
            for path in got if path in want and not close(path, got[path], want[path])]
