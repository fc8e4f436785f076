"""What ``aatest fleet interval|charts|diagnose`` and the station's fleet page do, without a CLI."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any

from aatest.fleet import archive, pages
from aatest.fleet.analysis import QuantityInterval, fleet_charts, fleet_diagnoses, unit_intervals
from aatest.fleet.control import ControlChart
from aatest.fleet.recurrence import RIG, RigSummary, summarise
from aatest.records.errors import RecordsError
from aatest.records.extract import datasheet_limits
from aatest.records.history import display_name
from aatest.records.lab import LabProfile
from aatest.records.store import RecordStore
from aatest.results.quantities import U_DIGITS, significant


@dataclass(frozen=True)
class Selection:
    """Which records the fleet views read."""

    records_url: str | None = None
    model: str | None = None
    since_utc: datetime | None = None
    include_simulations: bool = False


def _load(selection: Selection, serial: str | None = None) -> list[archive.FleetRecord]:
    with RecordStore.open(selection.records_url, create=False) as store:
        return archive.load(store, selection.model, serial, selection.since_utc,
                            selection.include_simulations)


def _interval_line(q: QuantityInterval, lab_months: int) -> str:
    label = display_name(q.name)[0]
    if q.fit is None or q.recommendation is None:
        return f"{label}: no interval — {q.reason}"
    r = q.recommendation
    per_year = q.fit.coefficients[0] * 365.25
    u_year = float(q.fit.covariance[0, 0]) ** 0.5 * 365.25
    days = "beyond the horizon" if r.days is None else f"{r.days:.0f} days"
    at_lab = float(r.reliability(lab_months * 365.25 / 12)[0])
    return (f"{label}: drift {per_year:+.4g} {q.unit}/year (u = "
            f"{significant(u_year, U_DIGITS)}), {len(q.fit.samples)} intervals; recommended "
            f"interval {days} for R = {r.target:g}; R at {lab_months} months = {at_lab:.3f}")


def interval(serial: str, selection: Selection, lab: LabProfile, target: float, degree: int,
             html: Path | None) -> str:
    """``aatest fleet interval SERIAL``: text per quantity; the page when ``html``."""
    rows = archive.calibrations_of(_load(selection, serial))
    if not rows:
        raise RecordsError(f"no calibration records of unit {serial!r}"
                           + ("" if selection.include_simulations else
                              " (simulations are left out: --include-simulations)"))
    with RecordStore.open(selection.records_url, create=False) as store:
        limits = datasheet_limits(store.results_of(rows[-1].record.id))
    intervals = unit_intervals(rows, limits, target, degree)
    months = lab.calibration_interval_months
    lines = [f"unit {serial}: {len(rows)} calibrations, reliability target {target:g}"]
    lines += [_interval_line(q, months) for q in intervals]
    if html is not None:
        pages.write(html, pages.interval_context(serial, rows[-1].record.model, intervals,
                                                 target, months, len(rows)))
        lines.append(f"page: {html}")
    return "\n".join(lines)


def charts(selection: Selection) -> tuple[list[ControlChart], int]:
    """The control charts of the selection and the count of groups too short for one."""
    return fleet_charts(_load(selection))


def charts_text(found: Sequence[ControlChart], short: int) -> str:
    """One line per chart with flagged points, then the totals."""
    lines = []
    for c in found:
        for s in c.signals:
            lines.append(f"out of control: {display_name(c.quantity)[0]} of model {c.model} "
                         f"({c.rig or 'all rigs'}): {c.serials[s.index]} "
                         f"{c.moments[s.index]:%Y-%m-%d} — {s.rule}: {s.description}")
    flagged = sum(1 for c in found if c.signals)
    lines.append(f"{len(found)} control charts, {flagged} with flagged points"
                 + (f"; {short} groups with fewer than three calibrations" if short else ""))
    return "\n".join(lines)


def diagnosis(selection: Selection, run_diagnose: bool) -> list[RigSummary]:
    """Per rig, the recurrence of every diagnosed effect."""
    runner = (lambda f: archive.diagnose_recording(f.record)) if run_diagnose else None
    return summarise(fleet_diagnoses(_load(selection), runner))


def diagnosis_text(summaries: Sequence[RigSummary]) -> str:
    lines = []
    for s in summaries:
        lines.append(f"rig {s.rig}: {len(s.diagnosed)} units diagnosed"
                     + (f", not diagnosed: {', '.join(s.undiagnosed)}" if s.undiagnosed else ""))
        lines += [f"  {e.effect}: {e.classification} ({len(e.units)}/{e.diagnosed} units: "
                  f"{', '.join(e.units)})" for e in s.effects]
    return "\n".join(lines) or "no diagnoses and no calibrations in the selection"


def rig_effects(summaries: Sequence[RigSummary]) -> int:
    """How many rig effects the summaries name (the CLI exits 1 when any)."""
    return sum(1 for s in summaries for e in s.effects if e.classification == RIG)


def overview_page(selection: Selection) -> str:
    """The station's fleet page: charts and the diagnosis from stored findings."""
    rows = _load(selection)
    found, short = fleet_charts(rows)
    context: dict[str, Any] = pages.overview_context(
        found, short, summarise(fleet_diagnoses(rows, None)))
    return pages.render(context)
