"""``aatest history --html``: trend plots of a unit's key quantities, in one self-contained file.

Each plot shows the calibrations over time with their expanded-uncertainty bars, the datasheet
limits, the fitted drift line (per year) and the next due date from the lab's interval.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from datetime import datetime
from pathlib import Path
from typing import Any

import matplotlib.dates as mdates
from jinja2.sandbox import ImmutableSandboxedEnvironment
from markupsafe import Markup

from aatest.presentation.figures import new_figure, to_svg
from aatest.records.history import display_name, fit_drift, next_due, quantity_names
from aatest.records.models import CalibrationRecord

_PAGE = """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>Calibration history — {{ serial }}</title>
<style>body{font-family:sans-serif;margin:2em;color:#222} table{border-collapse:collapse}
td,th{border:1px solid #ccc;padding:2px 8px;font-size:90%} figure{margin:1em 0}</style></head>
<body><h1>Calibration history of unit <span id="serial">{{ serial }}</span></h1>
<p>{{ records|length }} calibrations · lab {{ lab }} · next due
<b id="next-due">{{ due or "—" }}</b> (interval {{ interval }} months)</p>
<table id="records"><tr><th>calibrated (UTC)</th><th>procedure</th><th>certificate</th>
<th>verdict</th><th>bundle</th></tr>
{% for r in records %}<tr><td>{{ r.calibrated_utc.strftime("%Y-%m-%d %H:%M") }}</td>
<td>{{ r.procedure }}</td><td class="certificate">{{ r.certificate_number or "—" }}</td>
<td>{{ r.overall_verdict }}</td><td>{{ r.bundle }}</td></tr>{% endfor %}</table>
{% for plot in plots %}<figure class="trend" id="trend-{{ plot.name }}">{{ plot.svg }}
<figcaption>{{ plot.label }} [{{ plot.unit }}] — {{ plot.caption }}</figcaption></figure>
{% endfor %}</body></html>
"""


def _svg(figure: Any) -> Markup:
    return Markup(to_svg(figure, tight=True, inline=True))  # our own figure: trusted SVG


#: margin either side of the plotted dates, as a fraction of their span (at least a fortnight)
_MARGIN_FRACTION, _MARGIN_MIN_DAYS = 0.05, 14.0


def _date_axis(axes: Any, moments: Sequence[datetime]) -> None:
    """A time axis that spans every calibration and the due date, with a margin, and dated
    ticks a person reads (a single calibration no longer sits on the axis' edge)."""
    days = mdates.date2num(moments)
    margin = max(_MARGIN_FRACTION * float(days.max() - days.min()), _MARGIN_MIN_DAYS)
    axes.set_xlim(float(days.min()) - margin, float(days.max()) + margin)
    locator = mdates.AutoDateLocator(minticks=3, maxticks=8)
    axes.xaxis.set_major_locator(locator)
    axes.xaxis.set_major_formatter(mdates.ConciseDateFormatter(locator))
    axes.grid(True, axis="both", linewidth=0.5, alpha=0.4)


def _plot(records: Sequence[CalibrationRecord], name: str,
          limits: tuple[float, float] | None, due: datetime | None) -> tuple[Markup, str]:
    rows = [r for r in records if name in r.quantities]
    when = [r.calibrated_utc for r in rows]
    when_days = mdates.date2num(when)  # matplotlib's date numbers: the axis is a date axis
    values = [r.quantities[name].value for r in rows]
    errors = [r.quantities[name].expanded_uncertainty or 0.0 for r in rows]
    figure, grid = new_figure(1, 7.0, 3.0)
    axes = grid[0, 0]
    stated = any(r.quantities[name].expanded_uncertainty is not None for r in rows)
    axes.errorbar(when_days, values, yerr=errors, fmt="o", capsize=4,
                  label="calibration ± U" if stated else "calibration (U not stated)")
    if limits is not None:
        for bound in limits:
            axes.axhline(bound, color="tab:red", linestyle="--", linewidth=1)
        axes.plot([], [], color="tab:red", linestyle="--", label="datasheet limits")
    drift = fit_drift(records, name)
    caption = "drift: fewer than two calibrations on different days"
    if drift is not None:
        span = [when[0], due or when[-1]]
        axes.plot(mdates.date2num(span), [drift.at(t) for t in span], color="tab:gray",
                  label=f"drift {drift.per_year:+.3g}/year")
        caption = f"fitted drift {drift.per_year:+.4g} {drift.unit}/year over {drift.points} points"
    if due is not None:
        axes.axvline(float(mdates.date2num(due)), color="tab:green", linestyle=":",
                     label="next due")
    _date_axis(axes, [*when, *([due] if due is not None else [])])
    label, q = display_name(name)
    axes.set_ylabel(f"{label} [{q.unit}]")
    axes.legend(fontsize="small")
    return _svg(figure), caption


def write_trend_html(path: Path, serial: str, records: Sequence[CalibrationRecord],
                     limits: Mapping[str, tuple[float, float]], lab: str,
                     interval_months: int) -> Path:
    """Write the trend page of ``serial`` to ``path`` and return it."""
    due = next_due(records, interval_months)
    plots = []
    for name in quantity_names(records):
        svg, caption = _plot(records, name, limits.get(name), due)
        label, q = display_name(name)
        plots.append({"name": name, "label": label, "unit": q.unit, "svg": svg,
                      "caption": caption})
    # the page is ours, but every template renders sandboxed: one rule, no exceptions to audit
    env = ImmutableSandboxedEnvironment(autoescape=True)
    html = env.from_string(_PAGE).render(
        serial=serial, records=records, plots=plots, lab=lab, interval=interval_months,
        due=due.date().isoformat() if due else None)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(html, encoding="utf-8")
    return path
