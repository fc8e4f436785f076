"""The run summary on a terminal (rich tables), in a log (the same tables, plain) or as JSON.

rich decides from the console whether colour and box drawing apply; without a terminal the
tables are printed at a width that fits their content, so no line of a log is ever cut.
"""

from __future__ import annotations

import json
import math

from rich import box
from rich.console import Console
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


def summary_console(stream: object = None) -> Console:
    """A console on stdout: a terminal's own width, else :data:`LOG_WIDTH` (never cut)."""
    console = Console(file=stream, highlight=False)  # type: ignore[arg-type]
    if not console.is_terminal:
        console = Console(file=stream, highlight=False, width=LOG_WIDTH,  # type: ignore[arg-type]
                          no_color=True)
    return console


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
        ("Lab time", f"{duration_text(summary.lab_duration_s)} ({summary.steps} steps)"),
        ("Wall time", f"{duration_text(summary.wall_duration_s)} ({summary.command}; step "
                      f"loop {duration_text(summary.run_wall_duration_s)})"),
    ):
        table.add_row(label, value)
    return table


def print_summary(summary: RunSummary, console: Console | None = None) -> None:
    """The tables a person reads when ``run``/``analyze`` ends."""
    console = console or summary_console()
    if summary.certified:
        console.print(certified_table(summary))
    if summary.verdicts:
        console.print(verdict_table(summary))
    console.print(facts_table(summary))


def summary_json(summary: RunSummary) -> str:
    """``--json-summary``: the same summary as one JSON document."""
    return json.dumps(summary.as_json(), indent=2, allow_nan=False)
