"""The verdict banner's rows: exactly the engine's verdicts from ``results.json``.

The engine's verdict stage judges every certified quantity (docs/interfaces.md §1); the page
shows what it decided and never judges anything itself.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

KEYS = ("quantity", "channel", "value", "expanded_uncertainty", "limit", "unit", "verdict")


def banner(doc: Mapping[str, Any]) -> dict[str, Any]:
    """``overall`` and the verdict rows (value, U, limit, unit) of one results document."""
    rows = [{k: v.get(k) for k in KEYS} for v in doc.get("verdicts") or []]
    return {"overall": doc.get("overall", "none"), "verdicts": rows, "judged_by": "results"}
