"""What the engine stated about each result: values with U, and budgets, ready for templates.

Reads only what the uncertainty stage wrote (:class:`aatest.results.base.Certified` fields) on
the typed record: nothing here evaluates an uncertainty. A value the engine did not certify
shows without U. Names and units come from the quantity registry
(:mod:`aatest.results.quantities`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

from aatest.results import BudgetRow, RunResults
from aatest.results.base import Certified
from aatest.results.frf import FrfPoint
from aatest.results.quantities import DISTRIBUTIONS, QUANTITIES, Quantity, finite


@dataclass(frozen=True)
class Stated:
    """A value as the engine stated it, with its expanded uncertainty (None: not certified)."""

    value: float
    expanded_uncertainty: float | None


@dataclass(frozen=True)
class StaticQuantity:
    """A certified static quantity of one channel's result: where its value, U, k and budget
    are in the typed record."""

    quantity: Quantity
    entry: Callable[[RunResults, str], Certified | None]
    value: Callable[[Any], float | None]
    u: Callable[[Any], float | None]
    budget: Callable[[Any], list[BudgetRow]]


def _scale(results: RunResults, ch: str) -> Certified | None:
    return results.analysis.scale_factor.get(ch) if results.analysis.scale_factor else None


def _bias(results: RunResults, ch: str) -> Certified | None:
    return results.analysis.bias.get(ch) if results.analysis.bias else None


def _temperature(results: RunResults, ch: str) -> Certified | None:
    return results.analysis.temperature.get(ch) if results.analysis.temperature else None


#: every certified static quantity, in the order the report lists them
STATIC: tuple[StaticQuantity, ...] = (
    StaticQuantity(QUANTITIES["scale_factor"], _scale, lambda e: e.scale_v_per_dps2,
                   lambda e: e.expanded_uncertainty, lambda e: e.budget),
    StaticQuantity(QUANTITIES["bias"], _bias, lambda e: e.bias_v,
                   lambda e: e.expanded_uncertainty, lambda e: e.budget),
    StaticQuantity(QUANTITIES["g_sensitivity"], _bias, lambda e: e.g_sensitivity_dps2_per_g,
                   lambda e: e.g_sensitivity_expanded_uncertainty_dps2_per_g,
                   lambda e: e.g_sensitivity_budget),
    StaticQuantity(QUANTITIES["bias_coefficient_v_per_c"], _temperature,
                   lambda e: e.bias_coefficient_v_per_c, lambda e: e.expanded_uncertainty,
                   lambda e: e.budget),
    StaticQuantity(QUANTITIES["scale_coefficient_per_c"], _temperature,
                   lambda e: e.scale_coefficient_per_c,
                   lambda e: e.scale_coefficient_expanded_uncertainty_per_c,
                   lambda e: e.scale_coefficient_budget),
)


def static_values(results: RunResults, ch: str
                  ) -> Iterator[tuple[StaticQuantity, Certified, float]]:
    """(quantity, result entry, value) of every static quantity the channel's results state."""
    for q in STATIC:
        entry = q.entry(results, ch)
        value = finite(q.value(entry)) if entry is not None else None
        if entry is not None and value is not None:
            yield q, entry, value


def stated(results: RunResults, ch: str) -> dict[str, Stated]:
    """``quantity key → value with U`` of one channel's static results."""
    return {q.quantity.key: Stated(value, finite(q.u(entry)))
            for q, entry, value in static_values(results, ch)}


def frf_points(results: RunResults, ch: str) -> list[FrfPoint]:
    """The FRF points of one channel (empty without an FRF)."""
    return list(results.analysis.frf.get(ch) or []) if results.analysis.frf else []


def _value(value: float | None, u: float | None) -> Stated | None:
    shown = finite(value)
    return None if shown is None else Stated(shown, finite(u))


def frf_rows(results: RunResults, ch: str) -> list[dict[str, Any]]:
    """FRF points with their gain and phase (each value with U)."""
    return [{"point": p, "gain": _value(p.gain_db, p.gain_expanded_uncertainty_db),
             "phase": _value(p.phase_deg, p.phase_expanded_uncertainty_deg)}
            for p in frf_points(results, ch)]


def misalignment_rows(results: RunResults) -> list[dict[str, Any]]:
    """One row per scenario and sensor: δ and its U."""
    block = results.analysis.misalignment
    scenarios = block.scenarios if block is not None else {}
    return [{"scenario": s, "sensor": sensor, "delta_deg": entry.delta_deg,
             "u": _value(entry.delta_deg, entry.expanded_uncertainty), "entry": entry}
            for s, sensors in sorted(scenarios.items())
            for sensor, entry in sorted(sensors.items())]


def _budget(name: str, unit: str, value: float, u: float | None, k: float | None,
            rows: Sequence[BudgetRow]) -> dict[str, Any]:
    """A budget as printed: rows with their share of Σu_i² (the budget's own proportions).

    A contribution that is not finite (an overflow upstream) leaves every share unstated (—)
    rather than wrong.
    """
    values = [r.contribution if math.isfinite(r.contribution) else None for r in rows]
    total = sum(v**2 for v in values if v is not None)
    known = all(v is not None for v in values) and math.isfinite(total) and total > 0
    return {"name": name, "unit": unit, "value": value, "expanded_uncertainty": u, "k": k,
            "rows": [{**r.model_dump(), "distribution": DISTRIBUTIONS.get(r.distribution,
                                                                          r.distribution),
                      "share_pct": 100.0 * v**2 / total if known and v is not None else None}
                     for r, v in zip(rows, values, strict=True)]}


def _worst_frf(results: RunResults, ch: str) -> list[dict[str, Any]]:
    """The FRF point with the largest gain U: its gain and phase budgets (the table's worst)."""
    rated = [p for p in frf_points(results, ch)
             if p.gain_budget and p.gain_expanded_uncertainty_db is not None]
    if not rated:
        return []
    p = max(rated, key=lambda q: q.gain_expanded_uncertainty_db or 0.0)
    at = f"{ch} at {p.frequency_hz:.4f} Hz"
    gain, phase = QUANTITIES["frf_gain"], QUANTITIES["frf_phase"]
    return [_budget(f"{gain.name} {at}", gain.unit, p.gain_db, p.gain_expanded_uncertainty_db,
                    p.coverage_factor, p.gain_budget),
            _budget(f"{phase.name} {at}", phase.unit, p.phase_deg,
                    p.phase_expanded_uncertainty_deg,
                    p.phase_coverage_factor or p.coverage_factor, p.phase_budget)]


def budget_views(results: RunResults, channels: Sequence[str]) -> list[dict[str, Any]]:
    """Every budget the engine wrote: static quantities, the worst FRF point, misalignment."""
    out = []
    for ch in channels:
        for q, entry, value in static_values(results, ch):
            if q.budget(entry):
                out.append(_budget(f"{q.quantity.name} {ch}", q.quantity.unit, value,
                                   finite(q.u(entry)), entry.coverage_factor, q.budget(entry)))
        out += _worst_frf(results, ch)
    angle = QUANTITIES["misalignment"]
    for row in misalignment_rows(results):
        entry = row["entry"]
        if entry.budget:
            out.append(_budget(f"{angle.name} {row['sensor']} scenario {row['scenario']}",
                               angle.unit, entry.delta_deg, entry.expanded_uncertainty,
                               entry.coverage_factor, entry.budget))
    return out
