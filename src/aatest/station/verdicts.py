"""The verdict banner's rows: exactly the engine's verdicts, as the typed results state them.

The engine's verdict stage judges every certified quantity (docs/interfaces.md §1); the page
shows what it decided and never judges anything itself. Each quantity is shown by its name
and unit symbol from the quantity registry (:mod:`aatest.results.quantities`), its value and
expanded uncertainty rounded as on the certificate (GUM 7.2.6).
"""

from __future__ import annotations

from typing import Any

from aatest.results import RunResults
from aatest.results.quantities import quantity


def banner(results: RunResults) -> dict[str, Any]:
    """``overall`` and the verdict rows (value, U, limit, unit) of one run's results."""
    rows = []
    for v in results.verdicts:
        q = quantity(v.quantity)
        rows.append({"quantity": q.name, "key": v.quantity, "channel": v.channel,
                     "value": v.value, "expanded_uncertainty": v.expanded_uncertainty,
                     "limit": v.limit, "unit": q.unit, "digits": q.digits,
                     "verdict": v.verdict,
                     # as the certificate prints them: value ± U rounded per GUM 7.2.6
                     "measured": q.show(v.value, v.expanded_uncertainty),
                     "limit_text": q.limit_text(v.limit), "rule": v.rule})
    return {"overall": results.overall, "verdicts": rows, "judged_by": "results"}
