"""The fleet pages: view models of the three views, rendered by the sandboxed report engine.

The values are formatted here (names, units and digits from the quantity registry); the
template ``fleet.html.j2`` (beside the report templates) only lays them out, in the same
immutable sandbox and confined child process as every report; figures enter through the SVG
vetting (:func:`aatest.plugins.report.sandbox.vet_svg`).
"""

from __future__ import annotations

from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from aatest import __version__
from aatest.fleet.analysis import QuantityInterval
from aatest.fleet.control import ControlChart
from aatest.fleet.figures import control_plot, drift_plot
from aatest.fleet.interval import DAYS_PER_MONTH, HORIZON_DAYS
from aatest.fleet.recurrence import RigSummary
from aatest.plugins.report.sandbox import render_template, vet_svg
from aatest.records.history import display_name
from aatest.results.quantities import U_DIGITS, significant

TEMPLATE = "fleet.html.j2"
#: digits of a reliability, a share and a σ count on the page
_DIGITS = 3


def _page(kind: str, title: str, **content: Any) -> dict[str, Any]:
    return {"page": {"kind": kind, "title": title, "version": __version__,
                     "generated_utc": datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")},
            **content}


def _interval_text(q: QuantityInterval, lab_months: int) -> dict[str, str]:
    r = q.recommendation
    if r is None:
        return {"interval": "—", "at_lab": "—"}
    if r.days is None:
        interval = f"> {HORIZON_DAYS / 365.25:g} years"
    else:
        interval = f"{r.days:.0f} days ({r.days / DAYS_PER_MONTH:.1f} months)"
    at_lab = float(r.reliability(lab_months * DAYS_PER_MONTH)[0])
    return {"interval": interval, "at_lab": significant(at_lab, _DIGITS)}


def interval_context(serial: str, model: str, intervals: Sequence[QuantityInterval],
                     target: float, lab_months: int, calibrations: int) -> dict[str, Any]:
    """``aatest fleet interval SERIAL``: drift and recommended interval per quantity."""
    rows = []
    for q in intervals:
        label, registry = display_name(q.name)
        unit = q.unit or registry.unit
        fit = q.fit
        row: dict[str, Any] = {"name": q.name, "label": label, "unit": unit,
                               "reason": q.reason or "", **_interval_text(q, lab_months),
                               "figure": None}
        if fit is not None:
            per_year = fit.coefficients[0] * 365.25
            u_per_year = float(fit.covariance[0, 0]) ** 0.5 * 365.25
            row.update(drift=f"{per_year:+.4g} {unit}/year (u = "
                             f"{significant(u_per_year, U_DIGITS)})",
                       scatter=f"{significant(fit.s, U_DIGITS)} {unit}",
                       samples=len(fit.samples), dof=fit.dof,
                       weighting="1/u²" if fit.weighted else "equal",
                       figure=vet_svg(drift_plot(fit, q.recommendation, label, unit)))
        if q.recommendation is not None:
            low, high = q.recommendation.limits
            row["limits"] = f"{significant(low, registry.digits)} … " \
                            f"{significant(high, registry.digits)} {unit}"
        rows.append(row)
    return _page("interval", f"Calibration interval of unit {serial}", serial=serial,
                 model=model, quantities=rows, target=target, lab_months=lab_months,
                 calibrations=calibrations)


def _chart_row(chart: ControlChart) -> dict[str, Any]:
    label, registry = display_name(chart.quantity)
    low, high = chart.limits
    digits = registry.digits
    points = [{"when": chart.moments[s.index].strftime("%Y-%m-%d %H:%M"),
               "serial": chart.serials[s.index], "rule": s.rule, "why": s.description,
               "value": significant(float(chart.values[s.index]), digits)}
              for s in chart.signals]
    return {"quantity": chart.quantity, "label": label, "unit": registry.unit,
            "model": chart.model, "rig": chart.rig or "all rigs", "points": len(chart.values),
            "center": significant(chart.center, digits), "lcl": significant(low, digits),
            "ucl": significant(high, digits), "mr_bar": significant(chart.mr_bar, U_DIGITS),
            "mr_ucl": significant(chart.mr_ucl, U_DIGITS), "signals": points,
            "figure": vet_svg(control_plot(chart, label, registry.unit))}


def charts_context(charts: Sequence[ControlChart], short: int) -> dict[str, Any]:
    """``aatest fleet charts``: I-MR chart per model (and per rig) and quantity."""
    return _page("charts", "Control charts of the certified quantities",
                 charts=[_chart_row(c) for c in charts], short=short,
                 out_of_control=sum(1 for c in charts if c.signals))


def diagnose_context(summaries: Sequence[RigSummary]) -> dict[str, Any]:
    """``aatest fleet diagnose``: per rig, which effects are the rig's and which one unit's."""
    rigs = [{"rig": s.rig, "diagnosed": list(s.diagnosed), "undiagnosed": list(s.undiagnosed),
             "effects": [{"effect": e.effect, "classification": e.classification,
                          "units": ", ".join(e.units), "count": len(e.units),
                          "share": significant(e.share, _DIGITS)} for e in s.effects]}
            for s in summaries]
    return _page("diagnose", "Fleet diagnosis: rig effects and unit effects", rigs=rigs)


def render(context: dict[str, Any]) -> str:
    """The page's HTML (sandboxed, confined render)."""
    return render_template(TEMPLATE, context)


def write(path: Path, context: dict[str, Any]) -> Path:
    """Render ``context`` to ``path`` (parents created); the path."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(render(context), encoding="utf-8")
    return path


def overview_context(charts: Sequence[ControlChart], short: int,
                     summaries: Sequence[RigSummary]) -> dict[str, Any]:
    """The station's fleet page: the control charts and the fleet diagnosis together."""
    return {**charts_context(charts, short), **diagnose_context(summaries),
            **_page("overview", "Fleet: control charts and diagnosis")}
