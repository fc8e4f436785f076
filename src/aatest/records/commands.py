"""What ``aatest history``, ``records …`` and the records side of ``verify`` do, without the CLI."""

from __future__ import annotations

import json
from datetime import datetime
from pathlib import Path
from typing import Any

from rich import box
from rich.table import Table

from aatest.presentation.terminal import render_text
from aatest.records import audit
from aatest.records.errors import RecordsError
from aatest.records.export import write_csv
from aatest.records.extract import datasheet_limits
from aatest.records.history import history_json, history_text
from aatest.records.lab import LabProfile
from aatest.records.models import CalibrationRecord, RecordFilter
from aatest.records.store import RecordStore
from aatest.records.trend import write_trend_html
from aatest.records.url import is_default_missing, resolve_url
from aatest.records.verify import find_record, record_reasons, unregistered_reasons
from aatest.results.quantities import quantity
from aatest.results.rounding import measurement_text
from aatest.storage import locate


def _moment(text: str | None, option: str) -> datetime | None:
    try:
        return datetime.fromisoformat(text) if text else None
    except ValueError as exc:
        raise RecordsError(f"{option} {text!r}: expected an ISO date like 2026-01-31") from exc


def record_filter(serial: str | None, model: str | None, procedure: str | None,
                  verdict: str | None, since: str | None, until: str | None,
                  superseded: bool, include_simulations: bool = False) -> RecordFilter:
    """The query of ``records list|export`` from its options (dates in ISO form, UTC)."""
    return RecordFilter(serial=serial, model=model, procedure=procedure, verdict=verdict,
                        since_utc=_moment(since, "--since"), until_utc=_moment(until, "--until"),
                        include_superseded=superseded, include_simulations=include_simulations)


def open_for_reading(records_url: str | None) -> RecordStore:
    """The store to query; a SQLite file that does not exist is an error, not a new database."""
    return RecordStore.open(records_url, create=False)


def history(serial: str, records_url: str | None, lab: LabProfile, as_json: bool,
            html: Path | None, include_simulations: bool = False) -> str:
    """The text (or JSON) ``aatest history`` prints; writes the trend page when ``html``.

    Simulations are left out (also of the drift, trend and due date) unless
    ``include_simulations``; a unit with only simulations says so.
    """
    with open_for_reading(records_url) as store:
        records = store.history(serial, include_simulations)
        if not records:
            raise RecordsError(_no_history(store, serial, include_simulations))
        if html is not None:
            limits = datasheet_limits(store.results_of(records[-1].id))
            write_trend_html(html, serial, records, limits, lab.name,
                             lab.calibration_interval_months)
    if as_json:
        return json.dumps(history_json(serial, records), indent=2, allow_nan=False)
    text = history_text(serial, records, lab.calibration_interval_months)
    return text + (f"\ntrend plots: {html}" if html is not None else "")


def _no_history(store: RecordStore, serial: str, include_simulations: bool) -> str:
    message = f"no calibration records of unit {serial!r} in {store.name}"
    simulations = [] if include_simulations else store.history(serial, True)
    if simulations:
        message += (f" ({len(simulations)} simulation(s), never calibrations: "
                    "--include-simulations lists them)")
    return message


#: the quantity ``records list`` shows per record (the first channel's), with its U
LISTED_QUANTITY = "scale_factor"


def _listed_cell(record: CalibrationRecord) -> str:
    """The record's scale factor ± U, rounded per GUM 7.2.6, with its unit symbol."""
    name = next((n for n in sorted(record.quantities) if n.startswith(f"{LISTED_QUANTITY}.")),
                None)
    if name is None:
        return "—"
    stated, q = record.quantities[name], quantity(LISTED_QUANTITY)
    text = measurement_text(stated.value, stated.expanded_uncertainty, q.unit, digits=q.digits)
    return f"{text} ({name.partition('.')[2]})"


def records_table(records: list[CalibrationRecord]) -> Table:
    """``aatest records list``: one aligned row per record, with headers."""
    table = Table(box=box.SIMPLE_HEAD)
    for heading in ("Certificate", "Calibrated (UTC)", "Model", "Serial", "Procedure",
                    f"{quantity(LISTED_QUANTITY).name} ± U", "Verdict", "Command", "Kind",
                    "Bundle"):
        table.add_column(heading, no_wrap=True)
    for r in records:
        table.add_row(r.certificate_number or "—", f"{r.calibrated_utc:%Y-%m-%d %H:%M}",
                      r.model, r.serial, r.procedure, _listed_cell(r), r.overall_verdict,
                      r.command, r.kind, r.bundle)
    return table


def list_records(records_url: str | None, where: RecordFilter) -> str:
    """A table of the matching records (``aatest records list``)."""
    with open_for_reading(records_url) as store:
        records = store.query(where)
    return render_text(records_table(records)) if records else "no matching records"


def show_record(records_url: str | None, key: str) -> dict[str, Any]:
    """One record with the state of its files on disk (``aatest records show``)."""
    with open_for_reading(records_url) as store:
        record = store.get(key)
    document = record.model_dump(mode="json")
    report = locate(record.bundle)  # a path, or a URL on object storage
    document["bundle_problems"] = record_reasons(report, record) if report.parent.is_dir() else [
        f"bundle directory {report.parent} removed"]
    return document


def export_records(records_url: str | None, where: RecordFilter, path: Path) -> int:
    """Write matching records to ``path`` as CSV; how many."""
    with open_for_reading(records_url) as store:
        records = store.query(where)
    write_csv(path, records)
    return len(records)


def simulation_note(report: Path) -> str | None:
    """``simulation: …`` when the bundle's results are of a simulation (``aatest verify``)."""
    from aatest.engine.simulation import SIMULATION_TITLE, is_simulation, simulated_parts

    try:
        document = json.loads(report.with_name("results.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(document, dict) or not is_simulation(document):
        return None
    parts = ", ".join(simulated_parts(document.get("metadata") or {})) or "stated in results"
    return f"simulation ({SIMULATION_TITLE}; simulated: {parts})"


def verify_against_record(report: Path, records_url: str | None) -> tuple[list[str], str]:
    """Problems of ``report`` against its record, and a one-line note on what was checked."""
    url = resolve_url(records_url)
    if is_default_missing(url):
        return [], "no records store: bundle not checked against a record"
    with open_for_reading(records_url) as store:
        record = find_record(report, store)
        if record is None:
            return unregistered_reasons(report, store), f"no record of this bundle in {store.name}"
        label = record.certificate_number or f"record {record.id}"
        problems = record_reasons(report, record) + store.chain_problems(record.id)
        note = f"matches its record {label} in {store.name}"
        if record.certificate_number:
            with store.engine.connect() as connection:
                status = audit.status_of(connection, record.certificate_number)
                replaced = audit.supersedes(connection, record.certificate_number)
            if status is not None:  # no longer a valid certificate
                problems.append(f"certificate {record.certificate_number} was {status}")
            if replaced:
                note += f"; it supersedes {', '.join(replaced)}"
        return problems, note


def supersede(records_url: str | None, number: str, reason: str, by: str | None) -> str:
    """``aatest records supersede``: mark ``number`` superseded (by ``by``) or withdrawn."""
    with open_for_reading(records_url) as store:
        return audit.supersede(store, number, reason, by)


def audit_trail(records_url: str | None) -> tuple[bool, str]:
    """``aatest records audit``: every change to the store; whether its chain holds."""
    with open_for_reading(records_url) as store:
        found = audit.report(store)
    text = "\n".join(found.lines) or "no changes recorded"
    if found.broken is not None:
        return False, f"{text}\naudit trail broken at {found.broken}"
    return True, f"{text}\naudit trail intact: {len(found.lines)} change(s)"


def check_records(records_url: str | None) -> tuple[bool, str]:
    """``aatest records check``: recompute the chain; whether it holds, and what to print."""
    with open_for_reading(records_url) as store:
        report = store.check_chain()
        name = store.name
    if report.broken is not None:
        return False, (f"{name}: records chain broken at {report.broken.describe()} "
                       f"({report.count} record(s) before it hold)")
    return True, f"{name}: records chain intact: {report.count} record(s), head {report.head}"
