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
import time
import traceback
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from functools import wraps
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, TypeVar

import typer

from aatest.crash_report import write_crash_report

if TYPE_CHECKING:
    from aatest.results import RunResults
from aatest.engine.errors import EXIT_FINDING, EXIT_INTERNAL, EXIT_RIG_FAULT, AatestError

#: environment variables aatest reads, listed in ``aatest --help``
ENVIRONMENT_HELP = (
    "Environment: AATEST_RECORDS (records database URL), AATEST_LAB (lab profile YAML), "
    "AATEST_SIGNING_KEY (private key that signs reports), AATEST_SIGNING_PASSPHRASE (its "
    "passphrase), AATEST_OPERATOR (name on the certificate), AATEST_STATION_TOKEN (the "
    "station's access token), AATEST_WORKERS (analysis worker processes); for s3:// run "
    "directories AATEST_S3_ENDPOINT, AATEST_STORAGE_OPTIONS and AATEST_STAGING (docs/storage.md)."
)
#: the distributions ``aatest --version`` names beside aatest and Python
VERSION_DEPENDENCIES = ("numpy", "scipy", "pydantic", "typer", "rich", "mcap", "sqlalchemy",
                        "jinja2", "matplotlib", "cryptography")


def _flag_types_hidden() -> None:
    """Show no ``<bool>`` type beside a flag in help (``--pdf/--no-pdf`` says it all).

    typer ≥ 0.24 prints every option's type in the rich help, flags (and ``--help``)
    included; for a flag the type is noise. Flags keep their behaviour, only the help changes.
    """
    from typer.core import TyperOption

    shown = TyperOption.display_type_rich

    def display_type_rich(self: TyperOption, ctx: Any) -> str | None:
        return None if self.is_flag else shown(self, ctx)

    TyperOption.display_type_rich = display_type_rich  # type: ignore[method-assign]


_flag_types_hidden()

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="Characterise and calibrate angular accelerometers on turntables.",
    epilog=ENVIRONMENT_HELP,
)
sim_server_app = typer.Typer(no_args_is_help=True,
                             help="Serve the simulated rig over a real protocol.")
app.add_typer(sim_server_app, name="sim-server")
records_app = typer.Typer(no_args_is_help=True, help="Query the calibration records.")
app.add_typer(records_app, name="records")
references_app = typer.Typer(no_args_is_help=True,
                             help="The lab's reference standards and their due dates.")
app.add_typer(references_app, name="references")

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
        value = Path(value) if isinstance(value, str) and "://" not in value else value
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


def version_text() -> str:
    """aatest's version, Python's and those of the libraries results depend on."""
    import platform
    from importlib.metadata import PackageNotFoundError, version

    def of(name: str) -> str:
        try:
            return version(name)
        except PackageNotFoundError:
            return "not installed"

    lines = [f"aatest {of('aatest')}",
             f"Python {platform.python_version()} ({platform.python_implementation()}, "
             f"{platform.platform(terse=True)})"]
    lines += [f"{name} {of(name)}" for name in VERSION_DEPENDENCIES]
    return "\n".join(lines)


def _print_version(value: bool) -> None:
    if value:
        typer.echo(version_text())
        raise typer.Exit(0)


@app.callback()
def _main(
    debug: bool = typer.Option(False, "--debug/--no-debug",
                               help="Show tracebacks and debug logging."),
    version: bool = typer.Option(False, "--version", callback=_print_version, is_eager=True,
                                 help="Print the versions of aatest, Python and key libraries."),
) -> None:
    _state["debug"] = debug
    logging.basicConfig(level=logging.DEBUG if debug else logging.WARNING,
                        format="%(levelname)s: %(message)s", handlers=[_CurrentStderr()])


class _CurrentStderr(logging.StreamHandler):
    """Log to whatever ``sys.stderr`` is when a record is emitted, not the stream of the first
    call: the CLI run in-process (tests, the station) swaps ``sys.stderr`` per invocation, and
    a handler bound to the first one would write into a closed buffer afterwards."""

    @property
    def stream(self) -> Any:
        return sys.stderr

    @stream.setter
    def stream(self, _value: Any) -> None:
        """The stream is always the current ``sys.stderr``."""


_RECORDS_HELP = "Records database URL (default: the SQLite file in the user's data directory)"
_LAB_HELP = ("Lab profile YAML: name, address, accreditation, signatories, certificate prefix, "
             "interval")
_RIG_HELP = "Rig YAML (default: the simulated rig)"
_SIGN_KEY_HELP = ("Ed25519 private key that signs the report (passphrase from "
                  "AATEST_SIGNING_PASSPHRASE)")
_JSON_SUMMARY_HELP = "Print the closing summary as JSON on stdout instead of tables"
_RECORDS_ENV, _LAB_ENV, _SIGN_KEY_ENV = "AATEST_RECORDS", "AATEST_LAB", "AATEST_SIGNING_KEY"


_RECORDS_OPT = typer.Option(None, "--records", help=_RECORDS_HELP, envvar=_RECORDS_ENV)
_LAB_OPT = typer.Option(None, "--lab", help=_LAB_HELP, envvar=_LAB_ENV)
_LAB_TRUSTED_OPT = typer.Option(None, "--lab", help=_LAB_HELP + "; its signing_keys are trusted",
                                envvar=_LAB_ENV)
_SIGN_KEY_OPT = typer.Option(None, "--sign-key", help=_SIGN_KEY_HELP, envvar=_SIGN_KEY_ENV)
_RIG_OPT = typer.Option(None, "--rig", help=_RIG_HELP)


def _registering(records: str | None, lab: Path | None, command: str) -> Any:
    """The records scope of a command that produces a bundle (checks the URL up front)."""
    from aatest.records.hook import registering
    from aatest.records.lab import load_lab
    from aatest.records.url import resolve_url

    resolve_url(records)
    return registering(records, load_lab(lab), command)


#: ``--json`` is a flag (print JSON) everywhere; the file an option writes is ``--json-out``
_JSON_PATH_DEPRECATED = typer.Option(None, "--json", hidden=True,
                                     help="Deprecated name of --json-out")


def _json_out(json_out: Path | None, deprecated: Path | None) -> Path | None:
    """``--json-out``, or the deprecated ``--json PATH`` with a warning on stderr."""
    if deprecated is not None:
        typer.echo("warning: --json PATH is deprecated (--json is a flag elsewhere); "
                   "use --json-out PATH", err=True)
    return json_out or deprecated


def _where(target: str | None, exists: bool = True) -> Any:
    """A local path, or a location on object storage (``s3://…``; exit 2 naming a URL that
    does not exist when ``exists``); None stays None."""
    from aatest.storage import locate, require

    if target is None:
        return None
    return require(locate(target)) if exists else locate(target)


def _print_json(doc: Any) -> None:
    typer.echo(json.dumps(doc, indent=2, allow_nan=False))


@app.command()
@guarded
def validate(
    procedure: Path = typer.Argument(..., help="Procedure YAML"),
    rig: Path | None = _RIG_OPT,
    as_json: bool = typer.Option(False, "--json/--no-json",
                                 help="Print every preflight check with its status as JSON"),
    sign_key: Path | None = _SIGN_KEY_OPT,
    records: str | None = _RECORDS_OPT,
    lab: Path | None = _LAB_OPT,
    out: Path | None = typer.Option(None, "--out", help="Run directory (free space is "
                                    "checked there; default runs/)"),
) -> None:
    """Check, before anything moves, all a run needs (docs/interfaces.md "Preflight")."""
    from aatest.engine.analysis.coverage import usage_lines
    from aatest.preflight import Site, preflight

    report = preflight(procedure, rig, Site(lab, sign_key, records, out))
    if as_json:
        _print_json({"procedure": str(procedure), **report.to_json()})
        raise typer.Exit(0 if report.ok else 2)
    report.raise_if_failed()
    prepared = report.prepared
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
    for line in prepared.expansion.snapped_lines():  # nor moves silently
        typer.echo(line)
    for line in usage_lines(prepared.coverage):
        typer.echo(line)
    typer.echo("preflight:")
    for check in report.checks:
        typer.echo(f"  {check.name}: {check.status}: {check.message}")


@app.command()
@guarded
def plan(
    procedure: Path = typer.Argument(..., help="Procedure YAML"),
    rig: Path | None = _RIG_OPT,
    as_json: bool = typer.Option(False, "--json/--no-json",
                                 help="Print the expanded plan as JSON"),
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
    rig: Path | None = _RIG_OPT,
    out: str | None = typer.Option(None, "--out", help="Run directory: a path or an fsspec URL "
                                   "(s3://bucket/runs/r1; docs/storage.md)"),
    resume: bool = typer.Option(False, "--resume/--no-resume",
                                help="Continue an interrupted run in --out"),
    seed: int = typer.Option(0, "--seed", help="Seed of the simulated rig"),
    sign_key: Path | None = _SIGN_KEY_OPT,
    progress: bool = typer.Option(
        True, "--progress/--no-progress",
        help="Show progress: a bar on a terminal, one line per step otherwise (on stderr)"),
    operator: str | None = typer.Option(None, "--operator", help="Name on the certificate",
                                        envvar="AATEST_OPERATOR"),
    pdf: bool = typer.Option(False, "--pdf/--no-pdf",
                             help="Also print the report to PDF (needs Chromium)"),
    records: str | None = _RECORDS_OPT,
    lab: Path | None = _LAB_OPT,
    confirm_prompts: str = typer.Option(
        "ask", "--confirm-prompts",
        help="ask: a person confirms each operator prompt (refused without a terminal); "
        "auto: confirm them unattended (logged on the certificate)",
    ),
    serial: str | None = typer.Option(
        None, "--serial", envvar="AATEST_SERIAL",
        help="Serial of the unit calibrated (else the procedure's sensor.serial)"),
    model: str | None = typer.Option(None, "--model", help="Sensor model (else the procedure's)"),
    allow_overdue: str | None = typer.Option(
        None, "--allow-overdue", help="Run although a reference standard is overdue; the "
        "reason is printed on the certificate as a non-conformity"),
    json_summary: bool = typer.Option(False, "--json-summary/--no-json-summary",
                                      help=_JSON_SUMMARY_HELP),
) -> None:
    """Run a procedure: record both loggers, analyse, report (and sign), register the record."""
    from aatest.engine.errors import InputError
    from aatest.engine.run import session

    started = time.monotonic()
    if confirm_prompts not in ("ask", "auto"):
        raise InputError(f"--confirm-prompts: expected 'ask' or 'auto', got {confirm_prompts!r}")
    from aatest.preflight import Site, preflight

    unit = session.UnitName(serial or None, model or None)
    target = _where(out, exists=False)
    from aatest.storage import RemotePath, staging_dir

    # free space is measured where the recording is written: a URL's local staging directory
    local = staging_dir(target) if isinstance(target, RemotePath) else target
    checked = preflight(procedure, rig, Site(lab, sign_key, records, local, True, unit))
    checked.raise_if_failed()  # everything that would fail later fails before motion (exit 2)
    with _registering(records, lab, "run") as registrar:
        registrar.preflight = _check_references(registrar, rig, allow_overdue)
        run_dir, results = session.run(
            procedure, rig, target, resume, seed, sign_key, progress,
            operator=operator,
            pdf=pdf, confirm_prompts="auto" if confirm_prompts == "auto" else "ask",
            unit=unit, prepared=checked.prepared,
        )
    _print_summary(results, run_dir, "run", started, json_summary)
    _echo_kind(results)
    _exit_on_outcome(results)


def _check_references(registrar: Any, rig: Path | None,
                      allow_overdue: str | None) -> dict[str, Any]:
    """The rig file's reference standards checked against the register, before anything
    moves (exit 2 on an unknown, retired or — without ``--allow-overdue`` — overdue one)."""
    from datetime import UTC, datetime

    from aatest.engine.procedure.loader import load_rig
    from aatest.records import references

    names = load_rig(rig).references if rig is not None else ()
    if not names:
        return {}
    preflight = references.check(registrar.store(), names, datetime.now(UTC).date(),
                                 allow_overdue)
    for text in preflight.nonconformities:
        typer.echo(f"non-conformity: {text}", err=True)
    return preflight.metadata()


def _echo_kind(results: RunResults) -> None:
    """Say plainly when a run was a simulation (its number is of the SIM- series)."""
    from aatest.engine.simulation import (
        SIMULATION_TITLE,
        is_simulation,
        metadata_of,
        simulated_parts,
    )

    if is_simulation(results):
        parts = ", ".join(simulated_parts(metadata_of(results))) or "stated"
        number = results.certificate_number or "no number"
        typer.echo(f"simulation ({parts}): {SIMULATION_TITLE}, {number}")


def _print_summary(results: RunResults, bundle: Any, command: str, started: float,
                   as_json: bool) -> None:
    """The closing summary: rich tables (plain without a terminal) or ``--json-summary``."""
    from aatest.presentation.summary import summarise
    from aatest.presentation.terminal import print_summary, summary_json

    summary = summarise(results, bundle, command, time.monotonic() - started)
    if as_json:
        typer.echo(summary_json(summary))
    else:
        print_summary(summary)


def _exit_on_outcome(results: RunResults) -> None:
    """After everything is written: exit 2 on failed analyses, 1 on a failed verdict."""
    from aatest.metrology.verdicts import failed

    for name, message in results.analysis_errors.items():
        typer.echo(f"analysis {name}: {message}", err=True)
    if results.analysis_errors:
        raise typer.Exit(2)
    from aatest.results.quantities import quantity

    if failed(results):
        for v in results.verdicts:
            q = quantity(v.quantity)
            if v.verdict == "not judged":
                typer.echo(f"not judged: {q.name}, {v.channel}: {v.reason}", err=True)
            elif v.verdict != "pass":
                typer.echo(f"{v.verdict}: {q.name}, {v.channel}: {q.show(v.value)} vs limit "
                           f"{q.limit_text(v.limit)} ({v.rule} decision rule)", err=True)
        raise typer.Exit(EXIT_FINDING)


@app.command()
@guarded
def analyze(
    data: str = typer.Argument(
        ..., help="Run directory, recording.mcap, import directory or logger mapping.yaml (a "
        "run or recording may be an fsspec URL, e.g. s3://…)"),
    json_out: Path | None = typer.Option(None, "--json-out", help="Also write results here"),
    json_old: Path | None = _JSON_PATH_DEPRECATED,
    out: str | None = typer.Option(None, "--out", help="Where results/report go (default: DATA)"),
    sign_key: Path | None = _SIGN_KEY_OPT,
    records: str | None = _RECORDS_OPT,
    lab: Path | None = _LAB_OPT,
    json_summary: bool = typer.Option(False, "--json-summary/--no-json-summary",
                                      help=_JSON_SUMMARY_HELP),
) -> None:
    """Analyse recorded or imported data and write results.json and the report."""
    from aatest.bundle.signing_key import signing_key
    from aatest.engine.run import session

    started = time.monotonic()
    json_out = _json_out(json_out, json_old)
    where = _where(data)
    target = _where(out, exists=False) or (where if where.is_dir() else where.parent)
    wall = session.run_wall_duration(where) if where.is_dir() else None
    with _registering(records, lab, "analyze"):
        results = session.analyse_and_report(
            where, target, key_path=signing_key(sign_key), wall_duration_s=wall
        )
    if json_out is not None:
        from aatest.engine.analysis.results_file import results_json

        json_out.write_text(json.dumps(results_json(results), indent=2), encoding="utf-8")
    _print_summary(results, target, "analyze", started, json_summary)
    _exit_on_outcome(results)


@app.command()
@guarded
def export(
    run_dir: Path = typer.Argument(..., help="Run directory or recording"),
    csv: Path | None = typer.Option(None, "--csv", help="Output directory (import format)"),
    tdms: Path | None = typer.Option(None, "--tdms", help="Output directory (TDMS + mapping)"),
    mf4: Path | None = typer.Option(None, "--mf4", help="Output directory (MF4 + mapping)"),
) -> None:
    """Write a recording as CSV + dataset.yaml, or as a TDMS or MF4 file + mapping.yaml."""
    from aatest.engine.errors import InputError
    from aatest.recording import read_dataset
    from aatest.recording.data.exporter import export_csv
    from aatest.recording.data.logger_export import export_mf4, export_tdms

    chosen = [(w, d) for w, d in ((export_csv, csv), (export_tdms, tdms), (export_mf4, mf4))
              if d is not None]
    if len(chosen) != 1:
        raise InputError("export: give exactly one of --csv, --tdms, --mf4")
    writer, out_dir = chosen[0]
    path = writer(read_dataset(run_dir), out_dir)
    typer.echo(f"exported to {path}")


@app.command()
@guarded
def diagnose(
    data: str = typer.Argument(
        ..., help="Run directory, recording, import directory or logger mapping.yaml (a run "
        "or recording may be an fsspec URL)"),
    json_out: Path | None = typer.Option(None, "--json-out",
                                         help="Write the diagnosis JSON here"),
    json_old: Path | None = _JSON_PATH_DEPRECATED,
    model_out: Path | None = typer.Option(
        None, "--model-out", help="Write the extended model YAML"),
    records: str | None = _RECORDS_OPT,
    lab: Path | None = _LAB_OPT,
) -> None:
    """Show what the simulation gets wrong, name the cause, extend the model, measure the gain."""
    from aatest.diagnose.command import diagnose_command
    from aatest.records.hook import register_diagnosis

    json_out = _json_out(json_out, json_old)
    with _registering(records, lab, "diagnose") as registrar:
        findings = diagnose_command(_where(data), json_out, model_out)
        register_diagnosis(registrar, _where(data), json_out)
    raise typer.Exit(EXIT_FINDING if findings else 0)


@app.command()
@guarded
def misalignment(
    spectra: Path = typer.Argument(..., help="CSV: set, experiment, sensor, re, im"),
    as_json: bool = typer.Option(True, "--json/--no-json",
                                 help="Print the misalignment as JSON (the only format)"),
) -> None:
    """Misalignment of a three-sensor unit from fundamental spectral responses."""
    from aatest.plugins.analysis.misalignment import misalignment_from_spectra

    _print_json(misalignment_from_spectra(spectra))


@app.command()
@guarded
def report(
    run_dir: str = typer.Argument(..., help="Run directory with results.json (path or URL)"),
    template: Path | None = typer.Option(None, "--template", help="A lab's own template directory"),
    sign_key: Path | None = _SIGN_KEY_OPT,
    pdf: bool = typer.Option(False, "--pdf/--no-pdf",
                             help="Also print the report to PDF (needs Chromium)"),
    records: str | None = _RECORDS_OPT,
    lab: Path | None = _LAB_OPT,
) -> None:
    """Re-render (and sign) the report of a run; the new record supersedes the old one."""
    from aatest.engine.run import session

    with _registering(records, lab, "report"):
        typer.echo(f"report: {session.report(_where(run_dir), template, sign_key, pdf)}")


def _keygen_passphrase() -> str:
    """The new key's passphrase: ``AATEST_SIGNING_PASSPHRASE``, else asked at a terminal."""
    import os
    import sys

    from aatest.bundle.signing import SigningError
    from aatest.bundle.signing_key import PASSPHRASE_ENV

    secret = os.environ.get(PASSPHRASE_ENV) or (
        typer.prompt("passphrase", hide_input=True, confirmation_prompt=True)
        if sys.stdin.isatty() else "")
    if not secret:
        raise SigningError(f"keygen encrypts the private key: give a passphrase (in "
                           f"{PASSPHRASE_ENV} or at a terminal), or pass --no-passphrase")
    return str(secret)


@app.command()
@guarded
def keygen(
    keyfile: Path = typer.Argument(..., help="Private key file to create (public: KEYFILE.pub)"),
    passphrase: bool = typer.Option(
        True, "--passphrase/--no-passphrase",
        help="Encrypt the private key (default; passphrase from AATEST_SIGNING_PASSPHRASE, else "
             "asked); --no-passphrase writes it unencrypted"),
) -> None:
    """Create an Ed25519 signing key pair; print its fingerprint (for the lab profile)."""
    from aatest.bundle import signing

    fingerprint = signing.generate_keypair(keyfile, _keygen_passphrase() if passphrase else None)
    typer.echo(f"private key: {keyfile} (mode 0600, "
               f"{'encrypted' if passphrase else 'NOT encrypted'})\npublic key:  {keyfile}.pub"
               f"\nfingerprint: {fingerprint}")


@app.command()
@guarded
def verify(
    report_file: str = typer.Argument(
        ..., help="Signed report, or the bundle's directory (its signed report) (path or URL)"),
    public_key: Path | None = typer.Option(None, "--public-key",
                                           help="Trusted public key (beside the lab's keys)"),
    records: str | None = _RECORDS_OPT,
    lab: Path | None = _LAB_TRUSTED_OPT,
) -> None:
    """Check a signed bundle, its signing key and its record: exit 0 untouched, 1 tampered,
    untrusted or wrong key."""
    from aatest.bundle import signing
    from aatest.presentation.summary import signed_report
    from aatest.records.attest import signer_lines, trusted_keys
    from aatest.records.commands import simulation_note, verify_against_record

    report = _where(report_file)  # a missing local report is a finding (exit 1), a URL exit 2
    if report.is_dir():  # the bundle's directory: the report signed in it
        report = signed_report(report)
        report_file = str(report)
    result = signing.verify_bundle(report, trusted_keys(lab, public_key))
    record_problems, note = verify_against_record(report, records)
    if (simulated := simulation_note(report)) is not None:
        typer.echo(f"{report_file}: {simulated}")
    if result.ok and not record_problems:
        when = f", signed {result.signed_utc:%Y-%m-%d %H:%M} UTC" if result.signed_utc else ""
        typer.echo(f"{report_file}: signature valid ({result.format}{when}); {note}")
        for line in signer_lines(result, report):
            typer.echo(f"  {line}")
        return
    for reason in result.reasons + record_problems:
        typer.echo(f"{report_file}: {reason}", err=True)
    raise typer.Exit(EXIT_FINDING)


@app.command()
@guarded
def schema(
    results: bool = typer.Option(False, "--results/--no-results",
                                 help="The schema of results.json instead"),
    install: Path | None = typer.Option(
        None, "--install", help="Write both schemas into this directory (for editors) and "
        "print the modeline a procedure's first line takes"),
) -> None:
    """Print the procedure JSON Schema (for editors), or with --results that of results.json."""
    from aatest.schemas.export import install_schemas, render

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
                if kind == "effect":  # an effect's declaration is checked by aatest.effects
                    from aatest.effects import validate_declaration

                    validate_declaration(info.name, info.target, info.distribution)
                typer.echo(f"  {info.name:24s} {info.distribution} {info.version}")
            except PluginError as exc:
                typer.echo(f"  {ep.name:24s} BROKEN: {exc}")


_SIMULATIONS = typer.Option(
    False, "--include-simulations",
    help="Also list simulations (runs on a simulated rig; never calibrations)")


@app.command()
@guarded
def history(
    serial: str = typer.Argument(..., help="Unit serial number"),
    records: str | None = _RECORDS_OPT,
    as_json: bool = typer.Option(False, "--json/--no-json", help="Print the history as JSON"),
    html: Path | None = typer.Option(None, "--html", help="Write trend plots to this HTML file"),
    lab: Path | None = _LAB_OPT,
    include_simulations: bool = _SIMULATIONS,
) -> None:
    """A unit's calibrations: dates, certificates, key results ± U, verdicts, drift, next due."""
    from aatest.records import commands
    from aatest.records.lab import load_lab

    typer.echo(commands.history(serial, records, load_lab(lab), as_json, html,
                                include_simulations))


_SERIAL = typer.Option(None, "--serial", help="Unit serial number")
_MODEL = typer.Option(None, "--model", help="Sensor model")
_PROCEDURE = typer.Option(None, "--procedure", help="Procedure name")
_VERDICT = typer.Option(None, "--verdict", help="pass | fail | conditional-pass | ... | none")
_SINCE = typer.Option(None, "--since", help="Calibrated on/after (ISO date, UTC)")
_UNTIL = typer.Option(None, "--until", help="Calibrated on/before (ISO date, UTC)")
_SUPERSEDED = typer.Option(False, "--superseded/--no-superseded",
                           help="Include superseded records")
_RECORDS = _RECORDS_OPT


@records_app.command("list")
@guarded
def records_list(
    serial: str | None = _SERIAL, model: str | None = _MODEL,
    procedure: str | None = _PROCEDURE, verdict: str | None = _VERDICT,
    since: str | None = _SINCE, until: str | None = _UNTIL, superseded: bool = _SUPERSEDED,
    records: str | None = _RECORDS, include_simulations: bool = _SIMULATIONS,
) -> None:
    """List calibration records matching the filters, oldest first."""
    from aatest.records import commands

    where = commands.record_filter(serial, model, procedure, verdict, since, until, superseded,
                                   include_simulations)
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


@records_app.command("check")
@guarded
def records_check(
    records: str | None = _RECORDS_OPT,
) -> None:
    """Recompute the records' hash chain: exit 0 intact, 1 naming the first broken record."""
    from aatest.records.commands import check_records

    intact, message = check_records(records)
    if not intact:
        _fail(message, EXIT_FINDING)
    typer.echo(message)


@records_app.command("export")
@guarded
def records_export(
    csv: Path = typer.Option(..., "--csv", help="CSV file to write"),
    serial: str | None = _SERIAL, model: str | None = _MODEL,
    procedure: str | None = _PROCEDURE, verdict: str | None = _VERDICT,
    since: str | None = _SINCE, until: str | None = _UNTIL, superseded: bool = _SUPERSEDED,
    records: str | None = _RECORDS, include_simulations: bool = _SIMULATIONS,
) -> None:
    """Export matching records to CSV (one row per record, quantities as columns)."""
    from aatest.records import commands

    where = commands.record_filter(serial, model, procedure, verdict, since, until, superseded,
                                   include_simulations)
    typer.echo(f"exported {commands.export_records(records, where, csv)} records to {csv}")


@records_app.command("supersede")
@guarded
def records_supersede(
    number: str = typer.Argument(..., help="Certificate number"),
    reason: str = typer.Option(..., "--reason", help="Why (printed by verify and in the audit)"),
    by: str | None = typer.Option(None, "--by", help="The certificate that replaces it "
                                  "(without: withdrawn)"),
    records: str | None = _RECORDS,
) -> None:
    """Mark a certificate superseded by a newer one, or withdrawn; it is never changed."""
    from aatest.records import commands

    typer.echo(commands.supersede(records, number, reason, by))


@records_app.command("audit")
@guarded
def records_audit(records: str | None = _RECORDS) -> None:
    """Every change to the records store (who, when, what, why); exit 1 if its chain breaks."""
    from aatest.records import commands

    intact, text = commands.audit_trail(records)
    typer.echo(text)
    if not intact:
        raise typer.Exit(EXIT_FINDING)


@references_app.command("add")
@guarded
def references_add(
    identifier: str = typer.Argument(..., help="Identifier the rig file names, e.g. ENC-1"),
    kind: str = typer.Option(..., "--kind", help="encoder | rate-reference | data-logger | "
                             "thermometer | chamber"),
    certificate: str = typer.Option(..., "--certificate", help="Its calibration certificate"),
    issuing_lab: str = typer.Option(..., "--issuing-lab", help="Lab that calibrated it"),
    calibrated: str = typer.Option(..., "--calibrated", help="Calibration date (ISO)"),
    due: str = typer.Option(..., "--due", help="Due date (ISO)"),
    accuracy: str = typer.Option(..., "--accuracy", help="Stated accuracy, e.g. '±1 arcsec'"),
    records: str | None = _RECORDS,
) -> None:
    """Register a reference standard with its calibration and due date."""
    from pydantic import ValidationError

    from aatest.engine.errors import InputError
    from aatest.records import references
    from aatest.records.store import RecordStore

    try:
        reference = references.ReferenceStandard(
            identifier=identifier, kind=kind, certificate_number=certificate,
            issuing_lab=issuing_lab, calibrated_on=calibrated, due_on=due,
            accuracy=accuracy)
    except ValidationError as exc:
        problems = "; ".join(f"{'.'.join(map(str, e['loc'])) or 'reference'}: {e['msg']}"
                             for e in exc.errors())
        raise InputError(f"references add {identifier}: {problems}") from exc
    with RecordStore.open(records) as store:
        references.add(store, reference)
    typer.echo(f"registered reference {identifier} ({kind}), due {reference.due_on}")


@references_app.command("list")
@guarded
def references_list(
    include_retired: bool = typer.Option(False, "--retired", help="Include retired ones"),
    records: str | None = _RECORDS,
) -> None:
    """The registered reference standards, with OVERDUE marked."""
    from datetime import UTC, datetime

    from aatest.records import references
    from aatest.records.commands import open_for_reading

    today = datetime.now(UTC).date()
    with open_for_reading(records) as store:
        found = references.listing(store, include_retired)
    for r in found:
        state = "retired" if r.retired_utc else "OVERDUE" if r.overdue(today) else "in use"
        typer.echo(f"{r.identifier:12s} {r.kind:15s} {r.certificate_number:16s} "
                   f"{r.issuing_lab:20s} {r.calibrated_on} due {r.due_on}  {r.accuracy}  {state}")
    if not found:
        typer.echo("no reference standards registered")


@references_app.command("retire")
@guarded
def references_retire(
    identifier: str = typer.Argument(...),
    reason: str = typer.Option(..., "--reason", help="Why it is no longer used"),
    records: str | None = _RECORDS,
) -> None:
    """Take a reference standard out of use (it stays in the register)."""
    from aatest.records import references
    from aatest.records.commands import open_for_reading

    with open_for_reading(records) as store:
        references.retire(store, identifier, reason)
    typer.echo(f"retired reference {identifier}: {reason}")


@app.command()
@guarded
def station(
    host: str = typer.Option("127.0.0.1", "--host", help="Address to listen on (loopback default)"),
    port: int = typer.Option(8671, "--port", help="TCP port to listen on"),
    records: str | None = typer.Option(
        None, "--records", help="Records database URL for the units' history",
        envvar=_RECORDS_ENV),
    token_file: Path | None = typer.Option(
        None, "--token-file", help="File holding the access token (≥ 32 characters); the "
        "token itself may come from AATEST_STATION_TOKEN instead"
    ),
    runs: Path = typer.Option(Path("runs"), "--runs", help="Runs directory (new runs, history)"),
    procedures: Path | None = typer.Option(
        None, "--procedures", help="Directory of the lab's procedure YAMLs (beside the shipped)"),
    procedures_deprecated: Path | None = typer.Option(
        None, "--lab", hidden=True, help="Deprecated name of --procedures"),
    rig: Path | None = typer.Option(None, "--rig", help="Rig YAML (default: each procedure's)"),
    allow_host: list[str] = typer.Option(
        [], "--allow-host", help="Another Host name it answers to (NAME or NAME:PORT; repeatable)"
    ),
    sign_key: Path | None = _SIGN_KEY_OPT,
    archive: str | None = typer.Option(
        None, "--archive", help="Also upload each finished run to URL/<run name> (s3://…; "
        "docs/storage.md)"),
) -> None:
    """Serve the operator's station: run, watch and answer procedures from a browser."""
    from aatest.station.serve import StationOptions, serve

    if procedures_deprecated is not None:
        typer.echo("warning: station --lab is deprecated (--lab names a lab profile elsewhere); "
                   "use --procedures", err=True)
        procedures = procedures or procedures_deprecated
    serve(StationOptions(host=host, port=port, records=records, token_file=token_file,
                         runs_dir=runs, lab_dir=procedures, rig_file=rig,
                         allow_hosts=tuple(allow_host), sign_key=sign_key, archive=archive))


from aatest.testing.plugin_check import plugin_check  # noqa: E402 - a command of the kit's own

app.command("plugin-check")(guarded(plugin_check))


# the options every `aatest sim-server` command shares
SimHost = Annotated[str, typer.Option("--host", help="Address to listen on (loopback default)")]
SimPort = Annotated[int, typer.Option("--port", help="TCP port to listen on")]
SimSeed = Annotated[int, typer.Option("--seed", help="Seed of the simulated rig")]
SimCanInterface = Annotated[str | None, typer.Option(
    "--can-interface", help="python-can interface of the simulated CAN logger")]
SimCanChannel = Annotated[str | None, typer.Option(
    "--can-channel", help="python-can channel of the simulated CAN logger")]
SimSensor = Annotated[str | None, typer.Option(
    "--sensor", help="sensor model on the table (the procedure's sensor.model, e.g. "
    "sr207-aamu); its channels are the CAN logger's; default one reference sensor")]


@sim_server_app.command("modbus")
@guarded
def sim_server_modbus(host: SimHost = "127.0.0.1", port: SimPort = 5020, seed: SimSeed = 0,
                      can_interface: SimCanInterface = None,
                      can_channel: SimCanChannel = None, sensor: SimSensor = None) -> None:
    """Serve the simulated turntable over Modbus TCP (and its sensor logger on CAN)."""
    from aatest.twin.servers.modbus_server import serve_forever

    serve_forever(host, port, seed, can_interface=can_interface, can_channel=can_channel,
                  sensor=sensor)


@sim_server_app.command("acutrol")
@guarded
def sim_server_acutrol(
    host: SimHost = "127.0.0.1", port: SimPort = 9888, seed: SimSeed = 0,
    chamber: str = typer.Option("none", "--chamber",
                                help="also serve a chamber on the same twin: espec|simserv|none"),
    chamber_port: int | None = typer.Option(
        None, "--chamber-port", help="default the chamber's own port: espec 10001, simserv 2049"),
    can_interface: SimCanInterface = None, can_channel: SimCanChannel = None,
    sensor: SimSensor = None,
) -> None:
    """Serve the simulated ACUTROL-class table (its sensor logger on CAN, optionally a chamber)."""
    from aatest.twin.servers.acutrol_server import serve_forever as serve_acutrol

    if chamber not in _SIM_CHAMBER_PORTS and chamber != "none":
        raise typer.BadParameter("--chamber must be espec, simserv or none")
    serve_acutrol(host, port, seed, chamber=chamber,
                  chamber_port=chamber_port or _SIM_CHAMBER_PORTS.get(chamber, 0),
                  can_interface=can_interface, can_channel=can_channel, sensor=sensor)


#: the simulated chambers: their default port and what they are
_SIM_CHAMBER_PORTS = {"espec": 10001, "simserv": 2049}
_SIM_CHAMBER_TITLES = {"espec": "an ESPEC chamber (ASCII over TCP)",
                       "simserv": "a Weiss/Vötsch SIMSERV chamber"}


def _sim_chamber_command(kind: str) -> None:
    """``aatest sim-server KIND`` for a chamber simulator with its own twin."""

    def command(host: SimHost = "127.0.0.1", port: SimPort = _SIM_CHAMBER_PORTS[kind],
                seed: SimSeed = 0) -> None:
        from aatest.twin.servers.acutrol_server import serve_chamber_forever

        serve_chamber_forever(kind, host, port, seed)

    command.__doc__ = f"Serve {_SIM_CHAMBER_TITLES[kind]} simulated with its own twin."
    sim_server_app.command(kind)(guarded(command))


for _kind in _SIM_CHAMBER_PORTS:
    _sim_chamber_command(_kind)



from aatest.fleet.cli import build as _build_fleet  # noqa: E402 - needs guarded

app.add_typer(_build_fleet(guarded), name="fleet")


from aatest.batch import commands as _batch  # noqa: E402 - wrapped in the guard defined above

app.add_typer(_batch.batch_app(guarded), name="batch")
records_app.command("impact")(guarded(_batch.records_impact))


def main() -> None:
    """The ``aatest`` console script: a reader of stdout that goes away ends it quietly.

    Every command's output goes through one stdout (:mod:`aatest.cli_stdout`): when the reader
    closes the pipe (``aatest plugins | head -1``) the command unwinds through its ``finally``
    blocks (a run's rig stopped and closed) and exits 141 (128 + SIGPIPE) without a message.
    """
    from aatest.cli_stdout import EXIT_READER_GONE, ReaderAwareStdout, ReaderGone, silence_stdout

    sys.stdout = ReaderAwareStdout(sys.stdout)
    try:
        app()
    except ReaderGone:
        silence_stdout()
        sys.exit(EXIT_READER_GONE)


if __name__ == "__main__":
    main()
    sys.exit(0)
