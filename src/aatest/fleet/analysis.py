"""The fleet's three views computed from the archive: intervals, control charts, recurrence."""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from aatest.engine.errors import AnalysisError
from aatest.fleet.archive import FleetRecord, calibrations_of, diagnoses_of, stored_findings
from aatest.fleet.control import ControlChart, control_chart
from aatest.fleet.interval import (
    DriftFit,
    IntervalRecommendation,
    as_left_value,
    drift_samples,
    fit_deviation,
    recommend_interval,
    standard_uncertainty,
)
from aatest.fleet.recurrence import UnitDiagnosis
from aatest.records.history import quantity_names

ALL_RIGS = "all rigs"
#: "all rigs" and one rig name: a model seen on a single rig
_ONE_RIG = 2


@dataclass(frozen=True)
class QuantityInterval:
    """One quantity of one unit: its drift fit and interval, or why there is none."""

    name: str
    unit: str
    fit: DriftFit | None
    recommendation: IntervalRecommendation | None
    reason: str | None


def _interval_of(rows: Sequence[FleetRecord], name: str,
                 limits: tuple[float, float] | None, target: float,
                 degree: int) -> QuantityInterval:
    records = [f.record for f in rows if name in f.record.quantities]
    unit = records[-1].quantities[name].unit
    samples = drift_samples(records, name, {f.record.id: f.as_left for f in rows})
    try:
        fit = fit_deviation(samples, degree)
    except AnalysisError as exc:
        return QuantityInterval(name, unit, None, None, str(exc))
    if limits is None:
        return QuantityInterval(name, unit, fit, None,
                                "no tolerance limits stated for it (sensor datasheet)")
    last = [f for f in rows if name in f.record.quantities][-1]
    u_left = standard_uncertainty(last.record.quantities[name].expanded_uncertainty) or 0.0
    recommendation = recommend_interval(fit, as_left_value(last.record, name, last.as_left),
                                        u_left, limits, target)
    return QuantityInterval(name, unit, fit, recommendation, None)


def unit_intervals(rows: Sequence[FleetRecord], limits: Mapping[str, tuple[float, float]],
                   target: float, degree: int = 1) -> list[QuantityInterval]:
    """Every quantity of one unit's calibrations (oldest first), key quantities first."""
    calibrations = calibrations_of(rows)
    return [_interval_of(calibrations, name, limits.get(name), target, degree)
            for name in quantity_names([f.record for f in calibrations])]


def _chart(key: tuple[str, str, str], rows: list[FleetRecord]) -> ControlChart | None:
    model, rig, name = key
    return control_chart(name, model, None if rig == ALL_RIGS else rig,
                         [f.record.calibrated_utc for f in rows],
                         [f.record.serial for f in rows],
                         [f.record.quantities[name].value for f in rows])


def fleet_charts(rows: Sequence[FleetRecord]) -> tuple[list[ControlChart], int]:
    """I-MR charts per model and quantity (all rigs), then per model, rig and quantity when
    the model was calibrated on more than one rig; and how many groups had too few
    calibrations for a chart."""
    groups: dict[tuple[str, str, str], list[FleetRecord]] = defaultdict(list)
    for f in calibrations_of(rows):
        for name in f.record.quantities:
            groups[(f.record.model, ALL_RIGS, name)].append(f)
            groups[(f.record.model, f.rig, name)].append(f)
    rigs_of: dict[str, set[str]] = defaultdict(set)
    for model, rig, _ in groups:
        rigs_of[model].add(rig)
    charts, short = [], 0
    # a model calibrated on one rig only: its per-rig chart would repeat the all-rigs one
    order = sorted((k for k in groups if k[1] == ALL_RIGS or len(rigs_of[k[0]]) > _ONE_RIG),
                   key=lambda k: (k[0], k[2], k[1] != ALL_RIGS, k[1]))
    for key in order:
        chart = _chart(key, groups[key])
        if chart is None:
            short += 1
        else:
            charts.append(chart)
    return charts, short


def _stored(rows: Sequence[FleetRecord]) -> dict[tuple[str, str], UnitDiagnosis]:
    """The newest registered diagnosis with readable findings of each unit on each rig."""
    found: dict[tuple[str, str], UnitDiagnosis] = {}
    for f in diagnoses_of(rows):
        findings = stored_findings(f.record)
        if findings is not None:
            found[(f.rig, f.record.serial)] = UnitDiagnosis(
                f.record.serial, f.record.model, f.rig,
                frozenset(str(x["effect"]) for x in findings), f.record.bundle)
    return found


def fleet_diagnoses(rows: Sequence[FleetRecord],
                    run_diagnose: Callable[[FleetRecord], list[dict[str, Any]]] | None
                    ) -> list[UnitDiagnosis]:
    """Each unit on each rig with the effects of its newest diagnosis.

    A registered diagnosis whose findings are readable is used; any other unit (a calibration,
    or a diagnosis registered without its JSON) is diagnosed from its recording with
    ``run_diagnose`` when given, else listed as not diagnosed — never silently dropped.
    """
    found = _stored(rows)
    newest: dict[tuple[str, str], FleetRecord] = {}
    for f in rows:
        newest[(f.rig, f.record.serial)] = f
    for key, f in sorted(newest.items()):
        if key in found:
            continue
        effects = None
        if run_diagnose is not None:
            effects = frozenset(str(x["effect"]) for x in run_diagnose(f))
        found[key] = UnitDiagnosis(f.record.serial, f.record.model, f.rig, effects,
                                   "diagnosed now" if effects is not None else "not diagnosed")
    return [found[key] for key in sorted(found)]
