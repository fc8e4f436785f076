"""A unit's calibration history: the table, the JSON document, the drift and the due date.

The text table names each quantity as the quantity registry does (``Scale factor v_sz``, its
unit symbol and significant digits); the JSON keeps the record's ``QUANTITY.CHANNEL`` keys.
"""

from __future__ import annotations

import calendar
import math
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime
from typing import Any

import numpy as np
from rich import box
from rich.table import Table
from scipy.optimize import curve_fit

from aatest.presentation.terminal import render_text
from aatest.records.models import CalibrationRecord
from aatest.results.quantities import U_DIGITS, Quantity, quantity, significant
from aatest.results.rounding import measurement_text

SECONDS_PER_YEAR = 365.25 * 86400.0
#: the quantities a history shows, in this order (``NAME.CHANNEL`` prefixes)
KEY_QUANTITIES = ("scale_factor", "bias", "g_sensitivity", "frf_gain")


@dataclass(frozen=True)
class Drift:
    """A straight line through one quantity over time: slope per year ± its standard uncertainty."""

    name: str
    unit: str
    per_year: float
    u_per_year: float | None
    points: int
    origin_utc: datetime
    intercept: float

    def at(self, moment: datetime) -> float:
        """The fitted line's value at ``moment``."""
        years = (moment - self.origin_utc).total_seconds() / SECONDS_PER_YEAR
        return self.intercept + self.per_year * years


def history_json(serial: str, records: Sequence[CalibrationRecord]) -> dict[str, Any]:
    """``aatest history --json`` (docs/interfaces.md §1), oldest first."""
    return {"serial": serial, "records": [r.history_json() for r in records]}


def quantity_names(records: Sequence[CalibrationRecord]) -> list[str]:
    """Every quantity any record has, key quantities first, then by channel."""
    names = {n for r in records for n in r.quantities}
    return sorted(names, key=lambda n: (KEY_QUANTITIES.index(n.split(".")[0])
                                        if n.split(".")[0] in KEY_QUANTITIES else 99, n))


def _years(moments: Sequence[datetime]) -> np.ndarray:
    first = moments[0]
    return np.array([(m - first).total_seconds() / SECONDS_PER_YEAR for m in moments])


#: a straight line needs two points; its slope's uncertainty from the scatter needs a third
_POINTS_FOR_SLOPE = 2


def fit_drift(records: Sequence[CalibrationRecord], name: str) -> Drift | None:
    """Least-squares drift of ``name`` per year; weighted by 1/U² when every point states U.

    ``None`` with fewer than two calibrations or all on one day. The slope's uncertainty is
    the scaled covariance (needs three points).
    """
    rows = [r for r in records if name in r.quantities]
    if len(rows) < _POINTS_FOR_SLOPE:
        return None
    t_years = _years([r.calibrated_utc for r in rows])
    if np.ptp(t_years) * 365.25 < 1.0:
        return None
    values = np.array([r.quantities[name].value for r in rows])
    us = [r.quantities[name].expanded_uncertainty for r in rows]
    sigma = np.array(us, dtype=float) if all(u and u > 0 for u in us) else None
    params, cov = curve_fit(lambda t, a, b: a + b * t, t_years, values, sigma=sigma)
    scatter_known = len(rows) > _POINTS_FOR_SLOPE and math.isfinite(cov[1, 1])
    u_slope = math.sqrt(cov[1, 1]) if scatter_known else None
    return Drift(name, rows[0].quantities[name].unit, float(params[1]), u_slope, len(rows),
                 rows[0].calibrated_utc, float(params[0]))


def add_months(moment: datetime, months: int) -> datetime:
    """``moment`` plus whole calendar months (day clipped to the month's length)."""
    index = moment.month - 1 + months
    year, month = moment.year + index // 12, index % 12 + 1
    day = min(moment.day, calendar.monthrange(year, month)[1])
    return moment.replace(year=year, month=month, day=day)


def next_due(records: Sequence[CalibrationRecord], interval_months: int) -> datetime | None:
    """The next calibration date: the latest calibration plus the lab's interval (a
    simulation calibrates nothing, so it never sets a due date)."""
    calibrations = [r for r in records if r.kind != "simulation"]
    if not calibrations:
        return None
    return add_months(max(r.calibrated_utc for r in calibrations), interval_months)


def display_name(name: str) -> tuple[str, Quantity]:
    """``Scale factor v_sz`` and the registry entry of a record's ``scale_factor.v_sz``."""
    key, _, channel = name.partition(".")
    q = quantity(key)
    return f"{q.name} {channel}".strip(), q


def _quantity_cell(record: CalibrationRecord, name: str) -> str:
    """``value ± U`` rounded per GUM 7.2.6 (the unit is in the column heading)."""
    stated = record.quantities.get(name)
    if stated is None:
        return "—"
    q = display_name(name)[1]
    return measurement_text(stated.value, stated.expanded_uncertainty, digits=q.digits)


def _heading(records: Sequence[CalibrationRecord], name: str) -> str:
    label, q = display_name(name)
    return f"{label} ± U [{q.unit}]" if q.unit else f"{label} ± U"


def history_table(serial: str, records: Sequence[CalibrationRecord]) -> Table:
    """One row per calibration: date, procedure, certificate, the key quantities, verdict."""
    names = quantity_names(records)
    table = Table(title=f"Calibrations of unit {serial}", title_justify="left",
                  box=box.SIMPLE_HEAD)
    for heading in ("Calibrated (UTC)", "Procedure", "Certificate"):
        table.add_column(heading, no_wrap=True)
    for name in names:
        table.add_column(_heading(records, name), no_wrap=True, justify="right")
    table.add_column("Verdict", no_wrap=True)
    for r in records:
        table.add_row(r.calibrated_utc.strftime("%Y-%m-%d %H:%M"), r.procedure,
                      r.certificate_number or "—", *[_quantity_cell(r, n) for n in names],
                      r.overall_verdict + (" (simulation)" if r.kind == "simulation" else ""))
    return table


def history_text(serial: str, records: Sequence[CalibrationRecord], interval_months: int) -> str:
    """The table ``aatest history`` prints: one row per calibration, then drift and due date."""
    if not records:
        return f"{serial}: no calibration records"
    names = quantity_names(records)
    lines = [render_text(history_table(serial, records)), ""]
    for name in names:
        drift = fit_drift(records, name)
        if drift is not None:
            label, q = display_name(name)
            lines.append(f"drift of {label}: {drift.per_year:+.4g} {q.unit} per year"
                         f" (u = {significant(drift.u_per_year, U_DIGITS)}, "
                         f"{drift.points} calibrations)")
    due = next_due(records, interval_months)
    if due is not None:
        overdue = " — OVERDUE" if due < datetime.now(due.tzinfo) else ""
        lines.append(f"next due: {due.date().isoformat()}"
                     f" (interval {interval_months} months){overdue}")
    return "\n".join(lines)


