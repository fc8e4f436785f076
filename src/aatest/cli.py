"""``aatest`` command line (docs/interfaces.md §1).

The CLI is the one place where errors become exit codes: an :class:`AatestError` prints its
message (one line per located problem) and exits with its code; anything else is a bug: one
line, a crash report file and exit 4 (a traceback on the console only with ``--debug``).
"""

from __future__ import annotations

import json
import logging
import signal
import sys
import threading
import traceback
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from functools import wraps
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import typer

from aatest.crash_report import write_crash_report

if TYPE_CHECKING:
    from aatest.results import RunResults
from aatest.engine.errors import EXIT_FINDING, EXIT_INTERNAL, EXIT_RIG_FAULT, AatestError

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="Characterise and calibrate angular accelerometers on turntables.",
)
sim_server_app = typer.Typer(no_args_is_help=True,
                             help="Serve the simulated rig over a real protocol.")
app.add_typer(sim_server_app, name="sim-server")
records_app = typer.Typer(no_args_is_help=True, help="Query the calibration records.")
app.add_typer(records_app, name="records")

_state = {"debug": False}
F = TypeVar("F", bound=Callable[..., Any])


def _fail(message: str, code: int) -> None:
    typer.echo(message, err=True)
    raise typer.Exit(code)


def guarded(fn: F) -> F:
    """Translate errors into one-line messages and exit codes (docs/interfaces.md §1).

    aatest errors exit with their own code; an operator interrupt (Ctrl-C, SIGTERM) happens
    after the rig life cycle has reached its safe state and exits 3, resumable like a rig fault;
    anything else is a defect: one line, a crash report, exit 4 — never 1.
    """

    @wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            with _terminate_as_interrupt():
                return fn(*args, **kwargs)
        except (typer.Exit, typer.Abort):
            raise
        except AatestError as exc:
            if _state["debug"]:
                traceback.print_exc()
            _fail(f"error: {exc}" if "\n" not in str(exc) else str(exc), exc.exit_code)
        except KeyboardInterrupt as exc:
            _fail(f"interrupted ({str(exc) or 'SIGINT'}): the rig was brought to a safe state; "
                  "continue with --resume", EXIT_RIG_FAULT)
        except Exception as exc:  # noqa: BLE001 - the last line of defence
            if _state["debug"]:
                traceback.print_exc()
            try:
                report = f"crash report: {write_crash_report(exc, _run_dir_of(kwargs))}"
            except OSError as unwritable:  # e.g. a full disk: still one line and exit 4
                report = f"no crash report: {unwritable}"
            _fail(f"internal error: {type(exc).__name__}: {' '.join(str(exc).split())} "
                  f"({report}; rerun with --debug)", EXIT_INTERNAL)

    return wrapper  # type: ignore[return-value]


def _run_dir_of(kwargs: dict[str, Any]) -> Path | None:
    """The command's run directory (``--out`` or ``RUN_DIR``) when it names one."""
    for key in ("out", "run_dir"):
        value = kwargs.get(key)
        if isinstance(value, Path) and value.is_dir():
            return value
    return None


@contextmanager
def _terminate_as_interrupt() -> Iterator[None]:
    """Let SIGTERM unwind like Ctrl-C, so the rig's ``finally`` reaches its safe state."""

    def interrupt(_signum: int, _frame: Any) -> None:
        raise KeyboardInterrupt("SIGTERM")

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


@app.callback()
def _main(debug: bool = typer.Option(False, "--debug", help="Show tracebacks.")) -> None:
    _state["debug"] = debug
    logging.basicConfig(level=logging.DEBUG if debug else logging.WARNING,
                        format="%(levelname)s: %(message)s")


_RECORDS_HELP = "Records database URL (else AATEST_RECORDS, else the default SQLite file)"
_LAB_HELP = ("Lab profile YAML (else AATEST_LAB): name, address, accreditation, signatories, "
             "certificate prefix, interval")


def _registering(records: str | None, lab: Path | None, command: str) -> Any:
    """The records scope of a command that produces a bundle (checks the URL up front)."""
    from aatest.records.hook import registering
    from aatest.records.lab import load_lab
    from aatest.records.url import resolve_url

    resolve_url(records)
    return registering(records, load_lab(lab), command)


def _print_json(doc: Any) -> None:
    typer.echo(json.dumps(doc, indent=2, allow_nan=False))


@app.command()
@guarded
def validate(
    procedure: Path = typer.Argument(..., help="Procedure YAML"),
    rig: Path | None = typer.Option(None, "--rig", help="Rig YAML (default: simulated rig)"),
) -> None:
    """Check a procedure against its schema and the rig envelope; nothing moves."""
    from aatest.engine.analysis.coverage import usage_lines
    from aatest.engine.run.session import prepare

    prepared = prepare(procedure, rig)
    steps = prepared.plan.steps
    recorded = sum(1 for s in steps if s.recorded)
    typer.echo(
        f"{procedure}: OK — {recorded} step{'s' * (recorded != 1)}"
        + (f" (+ {len(steps) - recorded} chamber set-point changes)" if recorded < len(steps)
           else "")
        + f", lab duration {prepared.plan.lab_duration_s:.1f} s"
    )
    for line in prepared.expansion.skipped_lines():  # nothing disappears silently
        typer.echo(line)
    for line in usage_lines(prepared.coverage):
        typer.echo(line)


@app.command()
@guarded
def plan(
    procedure: Path = typer.Argument(..., help="Procedure YAML"),
    rig: Path | None = typer.Option(None, "--rig"),
    as_json: bool = typer.Option(False, "--json", help="Print the expanded plan as JSON"),
) -> None:
    """Expand the procedure's generators into the step list."""
    from aatest.engine.run.progress import describe
    from aatest.engine.run.session import prepare

    prepared = prepare(procedure, rig)
    expanded = prepared.plan
    if as_json:
        _print_json(prepared.plan_json())
        return
    for step in expanded.steps:
        typer.echo(f"{step.id:40s} {step.lab_duration_s:9.1f} s  {describe(step)}")
    typer.echo(f"{len(expanded.steps)} steps, lab duration {expanded.lab_duration_s:.1f} s")


@app.command()
@guarded
def run(
    procedure: Path = typer.Argument(..., help="Procedure YAML"),
    rig: Path | None = typer.Option(None, "--rig"),
    out: Path | None = typer.Option(None, "--out", help="Run directory"),
    resume: bool = typer.Option(False, "--resume", help="Continue an interrupted run in --out"),
    seed: int = typer.Option(0, "--seed", help="Seed of the simulated rig"),
    sign_key: Path | None = typer.Option(None, "--sign-key", help="Ed25519 private key"),
    no_progress: bool = typer.Option(False, "--no-progress"),
    operator: str | None = typer.Option(None, "--operator", help="Name on the certificate"),
    pdf: bool = typer.Option(False, "--pdf", help="Also print the report to PDF (needs Chromium)"),
    records: str | None = typer.Option(None, "--records", help=_RECORDS_HELP),
    lab: Path | None = typer.Option(None, "--lab", help=_LAB_HELP),
    confirm_prompts: str = typer.Option(
        "ask", "--confirm-prompts",
        help="ask: a person confirms each operator prompt (refused without a terminal); "
        "auto: confirm them unattended (logged on the certificate)",
    ),
) -> None:
    """Run a procedure: record both loggers, analyse, report (and sign), register the record."""
    from aatest.engine.errors import InputError
    from aatest.engine.run import session

    if confirm_prompts not in ("ask", "auto"):
        raise InputError(f"--confirm-prompts: expected 'ask' or 'auto', got {confirm_prompts!r}")
    with _registering(records, lab, "run"):
        run_dir, results = session.run(
            procedure, rig, out, resume, seed, sign_key, not no_progress, operator=operator,
            pdf=pdf, confirm_prompts="auto" if confirm_prompts == "auto" else "ask",
        )
    typer.echo(
        f"run complete: {run_dir} — {len(results.steps)} step{'s' * (len(results.steps) != 1)}, "
        f"lab {results.lab_duration_s:.1f} s, "
        f"wall {results.wall_duration_s:.1f} s"
    )
    _exit_on_outcome(results)


def _exit_on_outcome(results: RunResults) -> None:
    """After everything is written: exit 2 on failed analyses, 1 on a failed verdict."""
    from aatest.engine.analysis.verdicts import failed

    for name, message in results.analysis_errors.items():
        typer.echo(f"analysis {name}: {message}", err=True)
    if results.analysis_errors:
        raise typer.Exit(2)
    from aatest.results.quantities import quantity

    typer.echo(f"overall verdict: {results.overall}")
    if failed(results):
        for v in results.verdicts:
            q = quantity(v.quantity)
            if v.verdict == "not judged":
                typer.echo(f"not judged: {q.name}, {v.channel}: {v.reason}", err=True)
            elif v.verdict != "pass":
                typer.echo(f"{v.verdict}: {q.name}, {v.channel}: {q.show(v.value)} vs limit "
                           f"±{q.show(v.limit)} ({v.rule} decision rule)", err=True)
        raise typer.Exit(EXIT_FINDING)


@app.command()
@guarded
def analyze(
    data: Path = typer.Argument(..., help="Run directory, recording.mcap or import directory"),
    json_out: Path | None = typer.Option(None, "--json", help="Also write results here"),
    out: Path | None = typer.Option(None, "--out", help="Where results/report go (default: DATA)"),
    sign_key: Path | None = typer.Option(None, "--sign-key"),
    records: str | None = typer.Option(None, "--records", help=_RECORDS_HELP),
    lab: Path | None = typer.Option(None, "--lab", help=_LAB_HELP),
) -> None:
    """Analyse recorded or imported data and write results.json and the report."""
    from aatest.engine.run import session

    target = out or (data if data.is_dir() else data.parent)
    wall = session.run_wall_duration(data) if data.is_dir() else None
    with _registering(records, lab, "analyze"):
        results = session.analyse_and_report(
            data, target, key_path=session.signing_key(sign_key), wall_duration_s=wall
        )
    if json_out is not None:
        from aatest.engine.analysis.results import results_json

        json_out.write_text(json.dumps(results_json(results), indent=2), encoding="utf-8")
    typer.echo(f"analysed {len(results.steps)} steps → {target / 'results.json'}")
    _exit_on_outcome(results)


@app.command()
@guarded
def export(
    run_dir: Path = typer.Argument(..., help="Run directory or recording"),
    csv: Path = typer.Option(..., "--csv", help="Output directory (import format)"),
) -> None:
    """Write a recording in the measured-data import format (CSV + dataset.yaml)."""
    from aatest.engine.data.exporter import export_csv
    from aatest.engine.recording import read_dataset

    path = export_csv(read_dataset(run_dir), csv)
    typer.echo(f"exported to {path}")


@app.command()
@guarded
def diagnose(
    data: Path = typer.Argument(..., help="Run directory, recording or import directory"),
    json_out: Path | None = typer.Option(None, "--json", help="Write the diagnosis JSON here"),
    model_out: Path | None = typer.Option(
        None, "--model-out", help="Write the extended model YAML"),
    records: str | None = typer.Option(None, "--records", help=_RECORDS_HELP),
    lab: Path | None = typer.Option(None, "--lab", help=_LAB_HELP),
) -> None:
    """Show what the simulation gets wrong, name the cause, extend the model, measure the gain."""
    from aatest.diagnose.command import diagnose_command
    from aatest.records.hook import register_diagnosis

    with _registering(records, lab, "diagnose") as registrar:
        findings = diagnose_command(data, json_out, model_out)
        register_diagnosis(registrar, data, json_out)
    raise typer.Exit(EXIT_FINDING if findings else 0)


@app.command()
@guarded
def misalignment(
    spectra: Path = typer.Argument(..., help="CSV: set, experiment, sensor, re, im"),
    as_json: bool = typer.Option(True, "--json/--no-json"),
) -> None:
    """Misalignment of a three-sensor unit from fundamental spectral responses."""
    from aatest.plugins.analysis.misalignment import misalignment_from_spectra

    _print_json(misalignment_from_spectra(spectra))


@app.command()
@guarded
def report(
    run_dir: Path = typer.Argument(..., help="Run directory with results.json"),
    template: Path | None = typer.Option(None, "--template", help="A lab's own template directory"),
    sign_key: Path | None = typer.Option(None, "--sign-key"),
    pdf: bool = typer.Option(False, "--pdf", help="Also print the report to PDF (needs Chromium)"),
    records: str | None = typer.Option(None, "--records", help=_RECORDS_HELP),
    lab: Path | None = typer.Option(None, "--lab", help=_LAB_HELP),
) -> None:
    """Re-render (and sign) the report of a run; the new record supersedes the old one."""
    from aatest.engine.run import session

    with _registering(records, lab, "report"):
        typer.echo(f"report: {session.report(run_dir, template, sign_key, pdf)}")


@app.command()
@guarded
def keygen(
    keyfile: Path = typer.Argument(..., help="Private key file to create (public: KEYFILE.pub)"),
    passphrase: bool = typer.Option(False, "--passphrase", help="Ask for a passphrase"),
) -> None:
    """Create an Ed25519 signing key pair."""
    from aatest.engine.run import signing

    secret = (typer.prompt("passphrase", hide_input=True, confirmation_prompt=True)
              if passphrase else None)
    signing.generate_keypair(keyfile, secret)
    typer.echo(f"private key: {keyfile} (mode 0600)\npublic key:  {keyfile}.pub")


@app.command()
@guarded
def verify(
    report_file: Path = typer.Argument(..., help="Signed report"),
    public_key: Path | None = typer.Option(None, "--public-key", help="Trusted public key"),
    records: str | None = typer.Option(None, "--records", help=_RECORDS_HELP),
) -> None:
    """Check a signed report bundle and its record: exit 0 untouched, 1 tampered or wrong key."""
    from aatest.engine.run import signing
    from aatest.records.commands import verify_against_record

    result = signing.verify_bundle(report_file, public_key)
    record_problems, note = verify_against_record(report_file, records)
    if result.ok and not record_problems:
        typer.echo(f"{report_file}: signature valid; {note}")
        return
    for reason in result.reasons + record_problems:
        typer.echo(f"{report_file}: {reason}", err=True)
    raise typer.Exit(EXIT_FINDING)


@app.command()
@guarded
def schema(
    results: bool = typer.Option(False, "--results", help="The schema of results.json instead"),
    install: Path | None = typer.Option(
        None, "--install", help="Write both schemas into this directory (for editors) and "
        "print the modeline a procedure's first line takes"),
) -> None:
    """Print the procedure JSON Schema (for editors), or with --results that of results.json."""
    from aatest.engine.procedure.schema_export import install_schemas, render

    if install is not None:
        procedure_schema = install_schemas(install)
        typer.echo(f"wrote {procedure_schema} and results.schema.json; first line of a "
                   f"procedure:\n# yaml-language-server: $schema={procedure_schema}")
        return
    typer.echo(render(results), nl=False)


@app.command()
@guarded
def plugins() -> None:
    """List installed plugins per kind with distribution and version."""
    from aatest.engine import registry
    from aatest.engine.errors import PluginError
    from aatest.engine.interfaces import GROUPS

    for kind in GROUPS:
        typer.echo(f"{kind}:")
        for ep in registry.entry_points(kind):
            try:
                info = registry.load(kind, ep.name)
                typer.echo(f"  {info.name:24s} {info.distribution} {info.version}")
            except PluginError as exc:
                typer.echo(f"  {ep.name:24s} BROKEN: {exc}")


@app.command()
@guarded
def history(
    serial: str = typer.Argument(..., help="Unit serial number"),
    records: str | None = typer.Option(None, "--records", help=_RECORDS_HELP),
    as_json: bool = typer.Option(False, "--json", help="Print the history as JSON"),
    html: Path | None = typer.Option(None, "--html", help="Write trend plots to this HTML file"),
    lab: Path | None = typer.Option(None, "--lab", help=_LAB_HELP),
) -> None:
    """A unit's calibrations: dates, certificates, key results ± U, verdicts, drift, next due."""
    from aatest.records import commands
    from aatest.records.lab import load_lab

    typer.echo(commands.history(serial, records, load_lab(lab), as_json, html))


_SERIAL = typer.Option(None, "--serial")
_MODEL = typer.Option(None, "--model", help="Sensor model")
_PROCEDURE = typer.Option(None, "--procedure")
_VERDICT = typer.Option(None, "--verdict", help="pass | fail | conditional-pass | ... | none")
_SINCE = typer.Option(None, "--since", help="Calibrated on/after (ISO date, UTC)")
_UNTIL = typer.Option(None, "--until", help="Calibrated on/before (ISO date, UTC)")
_SUPERSEDED = typer.Option(False, "--superseded", help="Include superseded records")
_RECORDS = typer.Option(None, "--records", help=_RECORDS_HELP)


@records_app.command("list")
@guarded
def records_list(
    serial: str | None = _SERIAL, model: str | None = _MODEL,
    procedure: str | None = _PROCEDURE, verdict: str | None = _VERDICT,
    since: str | None = _SINCE, until: str | None = _UNTIL, superseded: bool = _SUPERSEDED,
    records: str | None = _RECORDS,
) -> None:
    """List calibration records matching the filters, oldest first."""
    from aatest.records import commands

    where = commands.record_filter(serial, model, procedure, verdict, since, until, superseded)
    typer.echo(commands.list_records(records, where))


@records_app.command("show")
@guarded
def records_show(
    key: str = typer.Argument(..., help="Certificate number or record id"),
    records: str | None = _RECORDS,
) -> None:
    """Show one record as JSON, with any file changed or removed since registration."""
    from aatest.records import commands

    _print_json(commands.show_record(records, key))


@records_app.command("export")
@guarded
def records_export(
    csv: Path = typer.Option(..., "--csv", help="CSV file to write"),
    serial: str | None = _SERIAL, model: str | None = _MODEL,
    procedure: str | None = _PROCEDURE, verdict: str | None = _VERDICT,
    since: str | None = _SINCE, until: str | None = _UNTIL, superseded: bool = _SUPERSEDED,
    records: str | None = _RECORDS,
) -> None:
    """Export matching records to CSV (one row per record, quantities as columns)."""
    from aatest.records import commands

    where = commands.record_filter(serial, model, procedure, verdict, since, until, superseded)
    typer.echo(f"exported {commands.export_records(records, where, csv)} records to {csv}")


@app.command()
@guarded
def station(
    host: str = typer.Option("127.0.0.1", "--host", help="Address to listen on (loopback default)"),
    port: int = typer.Option(8671, "--port"),
    records: str | None = typer.Option(None, "--records", help="Records store URL for history"),
    token_file: Path | None = typer.Option(
        None, "--token-file", help="Access token (≥ 32 characters; or AATEST_STATION_TOKEN)"
    ),
    runs: Path = typer.Option(Path("runs"), "--runs", help="Runs directory (new runs, history)"),
    lab: Path | None = typer.Option(None, "--lab", help="Lab directory of procedure YAMLs"),
    rig: Path | None = typer.Option(None, "--rig", help="Rig YAML (default: each procedure's)"),
) -> None:
    """Serve the operator's station: run, watch and answer procedures from a browser."""
    from aatest.station.serve import StationOptions, serve

    serve(StationOptions(host=host, port=port, records=records, token_file=token_file,
                         runs_dir=runs, lab_dir=lab, rig_file=rig))


@sim_server_app.command("modbus")
@guarded
def sim_server_modbus(
    host: str = typer.Option("127.0.0.1", "--host"),
    port: int = typer.Option(5020, "--port"),
    seed: int = typer.Option(0, "--seed"),
    can_interface: str | None = typer.Option(
        None, "--can-interface", help="python-can interface of the simulated CAN logger"),
    can_channel: str | None = typer.Option(None, "--can-channel"),
) -> None:
    """Serve the simulated turntable over Modbus TCP (and its sensor logger on CAN)."""
    from aatest.twin.servers.modbus_server import serve_forever

    can_options = {k: v for k, v in (("can_interface", can_interface),
                                     ("can_channel", can_channel)) if v}
    serve_forever(host, port, seed, **can_options)


def main() -> None:
    app()


if __name__ == "__main__":
    main()
    sys.exit(0)
