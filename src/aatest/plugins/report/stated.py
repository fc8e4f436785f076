"""What the engine stated about each result: values with U, and budgets, ready for templates.

Reads only what the uncertainty stage wrote (:class:`aatest.results.base.Certified` fields):
nothing here evaluates an uncertainty. A value the engine did not certify shows without U.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from aatest.engine.uncertainty import access as ex

#: (label, analysis key, value key, U key, budget key, unit) of each certified static quantity
_STATIC: tuple[tuple[str, str, str, str, str, str], ...] = (
    ("scale_factor", "scale_factor", "scale_v_per_dps2", "expanded_uncertainty", "budget",
     "V/(°/s²)"),
    ("bias", "bias", "bias_v", "expanded_uncertainty", "budget", "V"),
    ("g_sensitivity", "bias", "g_sensitivity_dps2_per_g",
     "g_sensitivity_expanded_uncertainty_dps2_per_g", "g_sensitivity_budget", "(°/s²)/g"),
    ("bias_coefficient_v_per_c", "temperature", "bias_coefficient_v_per_c",
     "expanded_uncertainty", "budget", "V/°C"),
    ("scale_coefficient_per_c", "temperature", "scale_coefficient_per_c",
     "scale_coefficient_expanded_uncertainty_per_c", "scale_coefficient_budget", "1/°C"),
)


def _value(entry: Mapping[str, Any], key: str, u_key: str) -> dict[str, Any] | None:
    value = ex.as_float(entry.get(key))
    if value is None:
        return None
    return {"value": value, "expanded_uncertainty": ex.as_float(entry.get(u_key))}


def stated(results: Mapping[str, Any], ch: str) -> dict[str, dict[str, Any]]:
    """``label → {value, expanded_uncertainty}`` of one channel's static results."""
    out = {}
    for label, block, key, u_key, _, _ in _STATIC:
        entry = ex.channel_entry(results, block, ch)
        shown = _value(entry, key, u_key) if isinstance(entry, Mapping) else None
        if shown is not None:
            out[label] = shown
    return out


def frf_rows(results: Mapping[str, Any], ch: str) -> list[dict[str, Any]]:
    """FRF points with their gain and phase (each ``{value, expanded_uncertainty}``)."""
    return [{"point": p, "gain": _value(p, "gain_db", "gain_expanded_uncertainty_db"),
             "phase": _value(p, "phase_deg", "phase_expanded_uncertainty_deg")}
            for p in ex.frf_points(results, ch)]


def misalignment_rows(results: Mapping[str, Any]) -> list[dict[str, Any]]:
    """One row per scenario and sensor: δ and its U."""
    return [{"scenario": s, "sensor": sensor, "delta_deg": entry.get("delta_deg"),
             "u": _value(entry, "delta_deg", "expanded_uncertainty")}
            for s, sensors in ex.misalignment_scenarios(results).items()
            for sensor, entry in sorted(sensors.items())]


def _budget(name: str, unit: str, value: Any, u: Any, k: Any, rows: Sequence[Mapping[str, Any]]
            ) -> dict[str, Any]:
    """A budget as printed: rows with their share of Σu_i² (the budget's own proportions).

    A contribution that is missing or not finite (``null`` in ``results.json``: an overflow
    upstream) leaves every share unstated (—) rather than wrong.
    """
    values = [ex.as_float(r.get("contribution")) for r in rows]
    total = sum(v**2 for v in values if v is not None)
    known = all(v is not None for v in values) and math.isfinite(total) and total > 0
    return {"name": name, "unit": unit, "value": value, "expanded_uncertainty": u, "k": k,
            "rows": [{**r, "share_pct": 100.0 * v**2 / total if known and v is not None
                      else None} for r, v in zip(rows, values, strict=True)]}


def _worst_frf(results: Mapping[str, Any], ch: str) -> list[dict[str, Any]]:
    """The FRF point with the largest gain U: its gain and phase budgets (the table's worst)."""
    rated = [p for p in ex.frf_points(results, ch) if p.get("gain_budget")]
    if not rated:
        return []
    p = max(rated, key=lambda q: ex.as_float(q.get("gain_expanded_uncertainty_db")) or 0.0)
    frequency_hz = ex.as_float(p.get("frequency_hz"))
    at = f"{ch} at {frequency_hz:.4f} Hz" if frequency_hz is not None else f"{ch}"
    return [_budget(f"FRF gain {at}", "dB", p["gain_db"], p["gain_expanded_uncertainty_db"],
                    p.get("coverage_factor"), p["gain_budget"]),
            _budget(f"FRF phase {at}", "deg", p["phase_deg"],
                    p.get("phase_expanded_uncertainty_deg"),
                    p.get("phase_coverage_factor") or p.get("coverage_factor"),
                    p.get("phase_budget") or [])]


def budget_views(results: Mapping[str, Any], channels: Sequence[str]) -> list[dict[str, Any]]:
    """Every budget the engine wrote: static quantities, the worst FRF point, misalignment."""
    out = []
    for ch in channels:
        for label, block, key, u_key, budget_key, unit in _STATIC:
            entry = ex.channel_entry(results, block, ch)
            if isinstance(entry, Mapping) and entry.get(budget_key):
                out.append(_budget(f"{label.replace('_', ' ')} {ch}", unit, entry[key],
                                   entry[u_key], entry.get("coverage_factor"), entry[budget_key]))
        out += _worst_frf(results, ch)
    for row in misalignment_rows(results):
        entry = ex.misalignment_scenarios(results)[row["scenario"]][row["sensor"]]
        if entry.get("budget"):
            out.append(_budget(f"misalignment {row['sensor']} scenario {row['scenario']}", "deg",
                               entry["delta_deg"], entry["expanded_uncertainty"],
                               entry.get("coverage_factor"), entry["budget"]))
    return out
