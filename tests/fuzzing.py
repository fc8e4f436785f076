"""The fuzz budget: a fixed, derandomised set of examples in CI, many more under ``-m slow``.

Every fuzz property is checked by two tests: the CI one draws a fixed number of examples, the
slow one (``-m slow``) :data:`SLOW_FACTOR` times as many; both derandomised (the same examples on
every machine, no example database), so a failure reproduces from the test id alone. The
oracle of every fuzz test is the CLI's contract: an input may be refused only with an
:class:`~aatest.engine.errors.AatestError` (exit 1, 2 or 3, with its file and location), never
with any other exception (exit 4, a traceback).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from hypothesis import HealthCheck, settings

from aatest.engine.errors import AatestError

#: the slow run's examples per CI example (``pytest -m slow -k fuzz``)
SLOW_FACTOR = 20
_COMMON: dict[str, Any] = {
    "derandomize": True, "deadline": None, "database": None, "print_blob": True,
    "suppress_health_check": [HealthCheck.function_scoped_fixture, HealthCheck.too_slow,
                              HealthCheck.filter_too_much, HealthCheck.data_too_large],
}


def budget(examples: int) -> Callable[[Any], Any]:
    """Hypothesis settings for ``examples`` derandomised examples."""
    return settings(max_examples=examples, **_COMMON)


def refused_cleanly(exc: BaseException) -> bool:
    """Whether ``exc`` is how the CLI may refuse an input: an aatest error, exit 1–3."""
    return isinstance(exc, AatestError) and exc.exit_code in (1, 2, 3)
