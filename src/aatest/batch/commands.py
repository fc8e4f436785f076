"""``aatest batch analyze|diagnose`` and ``aatest records impact`` (docs/batch.md).

The CLI wires these in with one line each; :func:`batch_app` takes the CLI's error guard so
errors become the same one-line messages and exit codes as everywhere else. Dask is imported
only when a batch runs, so ``aatest --help`` stays fast.

Exit codes: 2 when a task failed (its recording and error are printed) or the input is bad;
1 when every task completed and a re-analysis fails its verdict (``analyze``) or names a
finding (``diagnose``); 0 otherwise.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any

import typer

from aatest.engine.errors import EXIT_BAD_INPUT, EXIT_FINDING, InputError

_RECORDS_OPT = typer.Option(None, "--records", envvar="AATEST_RECORDS",
                            help="Records database URL (default: AATEST_RECORDS or the user's "
                            "default store)")
_SCHEDULER_OPT = typer.Option(None, "--scheduler",
                              help="An existing Dask scheduler (tcp://HOST:PORT); default: a "
                              "local cluster")
_WORKERS_OPT = typer.Option(2, "--workers", help="Worker processes of the local cluster")
_SIMULATIONS_OPT = typer.Option(False, "--include-simulations",
                                help="Also select records of simulated runs")
_SINCE_OPT = typer.Option(None, "--since", help="Calibrated on/after this ISO date")
_JSON_OPT = typer.Option(False, "--json/--no-json", help="Print JSON")
#: overall verdicts of a re-analysis that make the batch exit 1
FAILING = frozenset({"fail", "finding"})


def _since(text: str | None) -> datetime | None:
    try:
        return datetime.fromisoformat(text) if text else None
    except ValueError as exc:
        raise InputError(f"--since {text!r}: expected an ISO date like 2026-01-31") from exc


def _say(text: str) -> None:
    typer.echo(text, err=True)


@dataclass(frozen=True)
class Selection:
    """What ``aatest batch`` runs over: a prefix, or the records matching the options."""

    prefix: str | None = None
    serial: str | None = None
    procedure: str | None = None
    since: str | None = None
    reference: str | None = None
    include_simulations: bool = False

    def chosen(self, store: Any) -> list[Any]:
        """The selected recordings (:class:`~aatest.batch.selection.Selected`)."""
        from aatest.batch import selection
        from aatest.records.models import RecordFilter

        filters = (self.serial, self.procedure, self.since, self.reference)
        if self.prefix is not None and any(f is not None for f in filters):
            raise InputError("give either a PREFIX or record options (--serial, --procedure, "
                             "--since, --reference), not both")
        if self.prefix is not None:
            return selection.from_prefix(self.prefix, store)
        where = RecordFilter(serial=self.serial, procedure=self.procedure,
                             since_utc=_since(self.since),
                             include_simulations=self.include_simulations)
        found = selection.from_store(store, where, self.reference)
        if not found:
            raise InputError(f"no records in {store.name} match the selection")
        return found


def _batch(mode: str, chosen: Selection, records: str | None, scheduler: str | None,
           workers: int, as_json: bool) -> None:
    from aatest.batch import ledger
    from aatest.batch.runner import run_batch
    from aatest.records.store import RecordStore

    with RecordStore.open(records) as store:
        selected = chosen.chosen(store)
        report = run_batch(store, selected, "analyze" if mode == "analyze" else "diagnose",
                           scheduler=scheduler, workers=workers, progress=_say)
        subjects = {s.subject for s in selected}
        results = [r for r in ledger.stored(store, report.method_hash) if r.subject in subjects]
    failing = sorted(r.subject for r in results if r.overall_verdict in FAILING)
    if as_json:
        typer.echo(json.dumps(_report_json(report, results), indent=2, allow_nan=False))
    else:
        typer.echo(f"{mode}: {report.selected} recording(s), {report.skipped} done before, "
                   f"{len(report.completed)} now, {len(report.failures)} failed; method "
                   f"{report.method_hash[:12]}")
        for failure in report.failures:
            typer.echo(f"failed {failure.recording} ({failure.subject}): {failure.error}")
        label = "fail their verdict" if mode == "analyze" else "name a finding"
        typer.echo(f"{len(failing)} of {len(results)} re-analysed recording(s) {label}")
    if report.failures:
        raise typer.Exit(EXIT_BAD_INPUT)
    if failing:
        raise typer.Exit(EXIT_FINDING)


def _report_json(report: Any, results: list[Any]) -> dict[str, Any]:
    return {"method_hash": report.method_hash, "selected": report.selected,
            "skipped": report.skipped, "completed": report.completed,
            "failures": [f.__dict__ for f in report.failures],
            "worker_peak_mib": report.worker_peak_mib,
            "results": [{"subject": r.subject, "record_id": r.record_id,
                         "recording": r.recording, "overall_verdict": r.overall_verdict,
                         "quantities": r.quantities} for r in results]}


def batch_app(guard: Callable[[Any], Any]) -> typer.Typer:
    """The ``aatest batch`` sub-app, its commands wrapped in the CLI's error ``guard``."""
    app = typer.Typer(no_args_is_help=True,
                      help="Re-analyse or diagnose many recordings on a Dask cluster.")

    def make(mode: str) -> Callable[..., None]:
        def command(  # noqa: PLR0913, PLR0917 - the command's options one to one
            prefix: str | None = typer.Argument(
                None, help="Directory or URL prefix holding recordings (else: records)"),
            serial: str | None = typer.Option(None, "--serial", help="Records of this unit"),
            procedure: str | None = typer.Option(None, "--procedure",
                                                 help="Records of this procedure"),
            since: str | None = _SINCE_OPT,
            reference: str | None = typer.Option(
                None, "--reference", help="Records that used this reference standard"),
            include_simulations: bool = _SIMULATIONS_OPT,
            records: str | None = _RECORDS_OPT,
            scheduler: str | None = _SCHEDULER_OPT,
            workers: int = _WORKERS_OPT,
            as_json: bool = _JSON_OPT,
        ) -> None:
            chosen = Selection(prefix, serial, procedure, since, reference,
                               include_simulations)
            _batch(mode, chosen, records, scheduler, workers, as_json)

        verb = "Re-analyse" if mode == "analyze" else "Diagnose"
        command.__doc__ = (f"{verb} every selected recording; results are stored as "
                           "re-analyses linked to each record (certificates are unchanged).")
        return command

    for mode in ("analyze", "diagnose"):
        app.command(mode)(guard(make(mode)))
    return app


def records_impact(
    reference: str = typer.Option(..., "--reference", help="Identifier of the reference"),
    since: str | None = _SINCE_OPT,
    correction: Path | None = typer.Option(
        None, "--correction", help="Correction YAML: re-analyse with the corrected reference"),
    include_simulations: bool = _SIMULATIONS_OPT,
    records: str | None = _RECORDS_OPT,
    scheduler: str | None = _SCHEDULER_OPT,
    workers: int = _WORKERS_OPT,
    as_json: bool = _JSON_OPT,
) -> None:
    """Every certificate that used a reference; with --correction, old and new value ± U and
    whether each verdict changes (exit 1 when any does)."""
    from aatest.batch.correction import load_correction
    from aatest.batch.impact import assess, impact_json, impact_text
    from aatest.records.store import RecordStore

    fix = load_correction(correction) if correction is not None else None
    with RecordStore.open(records, create=False) as store:
        impact = assess(store, reference, fix, _since(since), include_simulations,
                        scheduler=scheduler, workers=workers, progress=_say)
    if as_json:
        typer.echo(json.dumps(impact_json(impact), indent=2, allow_nan=False))
    else:
        typer.echo(impact_text(impact))
    if impact.batch is not None and impact.batch.failures:
        raise typer.Exit(EXIT_BAD_INPUT)
    if any(cert.changes for cert in impact.certificates):
        raise typer.Exit(EXIT_FINDING)
