"""The verdict banner's rows: the engine's verdicts from ``results.json``, else the certificate's.

``results.json`` carries typed ``verdicts``/``overall`` once a verdict stage has judged the run
(docs/interfaces.md §1). Until then the judged quantities are those the calibration certificate
prints, computed by the report plugin from the same results with its default rig constants
(what ``aatest run`` renders), so the page and the signed report agree.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

KEYS = ("quantity", "channel", "value", "expanded_uncertainty", "limit", "unit", "verdict")


def banner(doc: Mapping[str, Any]) -> dict[str, Any]:
    """``overall`` and the verdict rows (value, U, limit, unit) of one results document."""
    rows = [{k: v.get(k) for k in KEYS} for v in doc.get("verdicts") or []]
    if rows:
        return {"overall": doc.get("overall", "none"), "verdicts": rows, "judged_by": "results"}
    from aatest.plugins.report.budgets import evaluate_all
    from aatest.plugins.report.uncertainty import RigConstants
    from aatest.plugins.report.verdicts import verdicts

    judged = verdicts(doc, evaluate_all(doc, RigConstants()).expanded())
    rows = [{"quantity": v.parameter, "channel": v.channel, "value": v.deviation,
             "expanded_uncertainty": v.expanded_uncertainty, "limit": v.limit, "unit": v.unit,
             "verdict": v.verdict} for v in judged]
    overall = "none" if not rows else ("pass" if all(v.passed for v in judged) else "fail")
    return {"overall": overall, "verdicts": rows, "judged_by": "certificate"}
