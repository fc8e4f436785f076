"""Small statistics the budgets share: finite numbers, 95 % intervals, Type A of a mean.

The results are typed (:class:`aatest.results.RunResults`); these helpers only turn the numbers
a result states into the standard uncertainties a budget needs.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

import numpy as np

from aatest.engine.errors import InputError
from aatest.numerics import Z95
from aatest.results._fields import finite

__all__ = ["PAIR", "Z95", "ResultsContractError", "ci_std", "finite", "finite_values",
           "std_of_mean"]

#: an interval is a pair of bounds; a mean needs at least two values
PAIR = 2


class ResultsContractError(InputError, LookupError):
    """The results lack a value docs/interfaces.md §1 promises."""


def finite_values(values: Iterable[float | None]) -> list[float]:
    """The finite ones of ``values``, in order."""
    return [v for v in values if v is not None and math.isfinite(v)]


def ci_std(interval: Sequence[float] | None) -> float | None:
    """Standard uncertainty from a 95 % interval ``[lo, hi]``: the half-width / :data:`Z95`.

    Large-sample fits: the interval is the estimate ± Z95 (≈1.96) standard uncertainties.
    """
    if interval is None or len(interval) != PAIR:
        return None
    lo, hi = finite(interval[0]), finite(interval[1])
    return abs(hi - lo) / (2 * Z95) if lo is not None and hi is not None else None


def std_of_mean(values: Sequence[float]) -> float | None:
    """Type A standard uncertainty of the mean, s/√n (None below two values)."""
    if len(values) < PAIR:
        return None
    return float(np.std(values, ddof=1) / math.sqrt(len(values)))
