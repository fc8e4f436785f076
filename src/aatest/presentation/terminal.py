"""The run summary on a terminal (rich tables), in a log (the same tables, plain) or as JSON.

rich decides from the console whether colour and box drawing apply; without a terminal the
tables are printed at a width that fits their content, so no line of a log is ever cut.
"""

from __future__ import annotations

import io
import json
import math

from rich import box
from rich.console import Console, RenderableType
from rich.table import Table

from aatest.presentation.summary import RunSummary

#: width of a console that is not a terminal: wide enough that rich never folds a cell
LOG_WIDTH = 400
_VERDICT_STYLE = {"pass": "green", "fail": "bold red", "conditional-pass": "yellow",
                  "conditional-fail": "red", "none": "dim"}


def duration_text(seconds: float) -> str:
    """``4.2 s``, ``12 min 05 s`` or ``2 h 03 min``: a duration a person reads at a glance."""
    if not math.isfinite(seconds) or seconds < 60:  # noqa: PLR2004 - seconds in a minute
        return f"{seconds:.1f} s"
    minutes, secs = divmod(round(seconds), 60)
    if minutes < 60:  # noqa: PLR2004 - minutes in an hour
        return f"{minutes} min {secs:02d} s"
    return f"{minutes // 60} h {minutes % 60:02d} min"


def _k(k: float | None) -> str:
    return "—" if k is None else f"k = {k:g}"


def certified_table(summary: RunSummary) -> Table:
    """Certified quantities: name, channel, value ± U, coverage factor."""
    table = Table(title="Certified results", box=box.SIMPLE_HEAD, title_justify="left")
    for heading in ("Quantity", "Channel", "Value ± U", "Coverage"):
        table.add_column(heading, no_wrap=True)
    for row in summary.certified:
        table.add_row(row.name, row.channel, row.text, _k(row.coverage_factor))
    return table


def verdict_table(summary: RunSummary) -> Table:
    """Verdicts: name, channel, value ± U, limit, decision rule, verdict."""
    table = Table(title="Verdicts", box=box.SIMPLE_HEAD, title_justify="left")
    for heading in ("Quantity", "Channel", "Value ± U", "Limit", "Rule", "Verdict"):
        table.add_column(heading, no_wrap=True)
    for row in summary.verdicts:
        style = _VERDICT_STYLE.get(row.verdict, "")
        table.add_row(row.name, row.channel, row.text, row.limit_text, row.rule,
                      f"[{style}]{row.verdict}[/]" if style else row.verdict)
    return table


def facts_table(summary: RunSummary) -> Table:
    """Overall verdict, certificate, report, unit, lab time and the command's wall time."""
    table = Table(box=None, show_header=False, padding=(0, 2, 0, 0))
    table.add_column(no_wrap=True, style="bold")
    table.add_column(no_wrap=True)
    style = _VERDICT_STYLE.get(summary.overall, "")
    unit = " ".join(p for p in (summary.model, summary.serial) if p) or "—"
    for label, value in (
        ("Overall verdict", f"[{style}]{summary.overall}[/]" if style else summary.overall),
        ("Certificate", summary.certificate_number or "— (no records store numbered it)"),
        ("Unit", unit),
        ("Report", summary.report_path or "—"),
        ("Results", summary.results_path),
        ("Lab time", f"{duration_text(summary.lab_duration_s)} ({summary.steps} "
                     f"step{'s' * (summary.steps != 1)})"),
        ("Wall time", f"{duration_text(summary.wall_duration_s)} ({summary.command}; step "
                      f"loop {duration_text(summary.run_wall_duration_s)})"),
    ):
        table.add_row(label, value)
    return table


def summary_tables(summary: RunSummary) -> list[Table]:
    """Certified results and verdicts (when there are any), then the facts of the run."""
    tables = [certified_table(summary)] if summary.certified else []
    tables += [verdict_table(summary)] if summary.verdicts else []
    return [*tables, facts_table(summary)]


def print_summary(summary: RunSummary, console: Console | None = None) -> None:
    """The tables a person reads when ``run``/``analyze`` ends, on stdout (or ``console``)."""
    if console is None:
        print(render_text(*summary_tables(summary)), flush=True)
        return
    for table in summary_tables(summary):
        console.print(table)


def summary_json(summary: RunSummary) -> str:
    """``--json-summary``: the same summary as one JSON document."""
    return json.dumps(summary.as_json(), indent=2, allow_nan=False)


def render_text(*renderables: RenderableType) -> str:
    """``renderables`` as text for stdout: a terminal's width and colour when stdout is one,
    else plain and as wide as the content (a table in a log is never folded or cut)."""
    probe = Console()
    width = probe.width if probe.is_terminal else LOG_WIDTH
    buffer = io.StringIO()
    console = Console(file=buffer, width=width, highlight=False,
                      force_terminal=probe.is_terminal, no_color=not probe.is_terminal)
    for renderable in renderables:
        console.print(renderable)
    return "\n".join(line.rstrip() for line in buffer.getvalue().splitlines()).strip("\n")
