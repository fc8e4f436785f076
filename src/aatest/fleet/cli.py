"""``aatest fleet interval|charts|diagnose``: what the lab's history says (docs/fleet.md).

Built by :func:`build` with the CLI's error guard, so the main CLI wires it with one line and
this package does not import the CLI back.
"""

from __future__ import annotations

from collections.abc import Callable
from datetime import datetime
from pathlib import Path
from typing import Any

import typer

from aatest.engine.errors import InputError

Command = Callable[..., Any]
#: the end-of-period reliability target unless the user names one
DEFAULT_RELIABILITY = 0.95
#: exit code of a finding: a flagged control-chart point, a rig effect
EXIT_FINDING = 1

_RECORDS = typer.Option(None, "--records", envvar="AATEST_RECORDS",
                        help="Records database URL (default: the user's SQLite file)")
_LAB = typer.Option(None, "--lab", envvar="AATEST_LAB",
                    help="Lab profile YAML (its calibration_interval_months)")
_MODEL = typer.Option(None, "--model", help="Only this sensor model")
_SINCE = typer.Option(None, "--since", help="Calibrated on/after (ISO date, UTC)")
_SIMULATIONS = typer.Option(False, "--include-simulations",
                            help="Also use simulations (never calibrations)")


def _since(text: str | None) -> datetime | None:
    try:
        return datetime.fromisoformat(text) if text else None
    except ValueError as exc:
        raise InputError(f"--since {text!r}: expected an ISO date like 2026-01-31") from exc


def build(guarded: Callable[[Command], Command]) -> typer.Typer:
    """The ``fleet`` sub-application, its commands wrapped in ``guarded``."""
    app = typer.Typer(no_args_is_help=True,
                      help="What the lab's history says: intervals, control charts, rig effects.")

    @app.command("interval")
    @guarded
    def interval(
        serial: str = typer.Argument(..., help="Unit serial number"),
        reliability: float = typer.Option(
            DEFAULT_RELIABILITY, "--reliability", min=0.0, max=1.0,
            help="End-of-period reliability target, strictly between 0 and 1"),
        degree: int = typer.Option(1, "--degree", min=1,
                                   help="Degree of the drift polynomial"),
        html: Path = typer.Option(None, "--html", help="Write the page here "
                                  "(default fleet-interval-SERIAL.html)"),
        records: str | None = _RECORDS, lab: Path | None = _LAB,
        include_simulations: bool = _SIMULATIONS,
    ) -> None:
        """Drift of each quantity and the interval that meets the reliability target."""
        from aatest.fleet.commands import Selection
        from aatest.fleet.commands import interval as run
        from aatest.records.lab import load_lab

        page = html or Path(f"fleet-interval-{serial}.html")
        typer.echo(run(serial, Selection(records, None, None, include_simulations),
                       load_lab(lab), reliability, degree, page))

    @app.command("charts")
    @guarded
    def charts(
        html: Path = typer.Option(Path("fleet-charts.html"), "--html", help="Write the page here"),
        model: str | None = _MODEL, since: str | None = _SINCE, records: str | None = _RECORDS,
        include_simulations: bool = _SIMULATIONS,
    ) -> None:
        """I-MR control charts of every certified quantity per model and rig (exit 1: flags)."""
        from aatest.fleet import commands, pages

        found, short = commands.charts(
            commands.Selection(records, model, _since(since), include_simulations))
        pages.write(html, pages.charts_context(found, short))
        typer.echo(commands.charts_text(found, short) + f"\npage: {html}")
        if any(c.signals for c in found):
            raise typer.Exit(EXIT_FINDING)

    @app.command("diagnose")
    @guarded
    def diagnose(
        html: Path = typer.Option(Path("fleet-diagnose.html"), "--html",
                                  help="Write the page here"),
        run_diagnose: bool = typer.Option(
            False, "--run-diagnose/--stored-only",
            help="Diagnose the recordings of units without stored findings"),
        model: str | None = _MODEL, since: str | None = _SINCE, records: str | None = _RECORDS,
        include_simulations: bool = _SIMULATIONS,
    ) -> None:
        """Which discrepancy effects recur across a rig's units (exit 1: a rig effect)."""
        from aatest.fleet import commands, pages

        summaries = commands.diagnosis(
            commands.Selection(records, model, _since(since), include_simulations), run_diagnose)
        pages.write(html, pages.diagnose_context(summaries))
        hint = "" if summaries or include_simulations else (
            " (simulations are left out: --include-simulations)")
        typer.echo(commands.diagnosis_text(summaries) + hint + f"\npage: {html}")
        if commands.rig_effects(summaries):
            raise typer.Exit(EXIT_FINDING)

    return app
