"""``aatest`` command line (docs/interfaces.md §1).

The CLI is the one place where errors become exit codes: an :class:`AatestError` prints its
message (one line per located problem) and exits with its code; anything else is a bug and
prints a traceback only with ``--debug``.
"""

from __future__ import annotations

import json
import logging
import sys
import traceback
from collections.abc import Callable
from functools import wraps
from pathlib import Path
from typing import Any, Optional, TypeVar

import typer

from aatest.engine.errors import EXIT_FINDING, AatestError

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="Characterise and calibrate angular accelerometers on turntables.",
)
sim_server_app = typer.Typer(no_args_is_help=True, help="Serve the simulated rig over a real protocol.")
app.add_typer(sim_server_app, name="sim-server")

_state = {"debug": False}
F = TypeVar("F", bound=Callable[..., Any])


def _fail(message: str, code: int) -> None:
    typer.echo(message, err=True)
    raise typer.Exit(code)


def guarded(fn: F) -> F:
    """Translate aatest errors into one-line messages and exit codes."""

    @wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return fn(*args, **kwargs)
        except (typer.Exit, typer.Abort):
            raise
        except AatestError as exc:
            if _state["debug"]:
                traceback.print_exc()
            _fail(f"error: {exc}" if "\n" not in str(exc) else str(exc), exc.exit_code)
        except KeyboardInterrupt:
            _fail("interrupted: the rig was brought to a safe state; continue with --resume", 3)
        except Exception as exc:  # noqa: BLE001 - the last line of defence
            if _state["debug"]:
                traceback.print_exc()
            _fail(f"internal error: {type(exc).__name__}: {exc} (rerun with --debug)", 1)

    return wrapper  # type: ignore[return-value]


@app.callback()
def _main(debug: bool = typer.Option(False, "--debug", help="Show tracebacks.")) -> None:
    _state["debug"] = debug
    logging.basicConfig(level=logging.DEBUG if debug else logging.WARNING, format="%(levelname)s: %(message)s")


def _print_json(doc: Any) -> None:
    typer.echo(json.dumps(doc, indent=2, allow_nan=False))


@app.command()
@guarded
def validate(
    procedure: Path = typer.Argument(..., help="Procedure YAML"),
    rig: Optional[Path] = typer.Option(None, "--rig", help="Rig YAML (default: simulated rig)"),
) -> None:
    """Check a procedure against its schema and the rig envelope; nothing moves."""
    from aatest.engine.run.session import prepare

    prepared = prepare(procedure, rig)
    typer.echo(
        f"{procedure}: OK — {len(prepared.plan.steps)} steps, "
        f"lab duration {prepared.plan.lab_duration_s:.1f} s"
    )


@app.command()
@guarded
def plan(
    procedure: Path = typer.Argument(..., help="Procedure YAML"),
    rig: Optional[Path] = typer.Option(None, "--rig"),
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
    rig: Optional[Path] = typer.Option(None, "--rig"),
    out: Optional[Path] = typer.Option(None, "--out", help="Run directory"),
    resume: bool = typer.Option(False, "--resume", help="Continue an interrupted run in --out"),
    seed: int = typer.Option(0, "--seed", help="Seed of the simulated rig"),
    sign_key: Optional[Path] = typer.Option(None, "--sign-key", help="Ed25519 private key"),
    no_progress: bool = typer.Option(False, "--no-progress"),
    operator: Optional[str] = typer.Option(None, "--operator", help="Name on the certificate"),
    pdf: bool = typer.Option(False, "--pdf", help="Also print the report to PDF (needs Chromium)"),
    confirm_prompts: str = typer.Option(
        "ask", "--confirm-prompts",
        help="ask: a person confirms each operator prompt (refused without a terminal); "
        "auto: confirm them unattended (logged on the certificate)",
    ),
) -> None:
    """Run a procedure: record both loggers, analyse, report (and sign)."""
    from aatest.engine.errors import InputError
    from aatest.engine.run import session

    if confirm_prompts not in ("ask", "auto"):
        raise InputError(f"--confirm-prompts: expected 'ask' or 'auto', got {confirm_prompts!r}")
    run_dir, results = session.run(
        procedure, rig, out, resume, seed, sign_key, not no_progress, operator=operator, pdf=pdf,
        confirm_prompts="auto" if confirm_prompts == "auto" else "ask",
    )
    typer.echo(
        f"run complete: {run_dir} — {len(results['steps'])} steps, lab {results['lab_duration_s']:.1f} s, "
        f"wall {results['wall_duration_s']:.1f} s"
    )
    _report_analysis_errors(results)


def _report_analysis_errors(results: dict[str, Any]) -> None:
    errors = results.get("analysis_errors") or {}
    for name, message in errors.items():
        typer.echo(f"analysis {name}: {message}", err=True)
    if errors:
        raise typer.Exit(2)


@app.command()
@guarded
def analyze(
    data: Path = typer.Argument(..., help="Run directory, recording.mcap or import directory"),
    json_out: Optional[Path] = typer.Option(None, "--json", help="Also write results here"),
    out: Optional[Path] = typer.Option(None, "--out", help="Where results/report go (default: DATA)"),
    sign_key: Optional[Path] = typer.Option(None, "--sign-key"),
) -> None:
    """Analyse recorded or imported data and write results.json and the report."""
    from aatest.engine.run import session

    target = out or (data if data.is_dir() else data.parent)
    wall = session.run_wall_duration(data) if data.is_dir() else None
    results = session.analyse_and_report(
        data, target, key_path=session.signing_key(sign_key), wall_duration_s=wall
    )
    if json_out is not None:
        json_out.write_text(json.dumps(results, indent=2), encoding="utf-8")
    typer.echo(f"analysed {len(results['steps'])} steps → {target / 'results.json'}")
    _report_analysis_errors(results)


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
    json_out: Optional[Path] = typer.Option(None, "--json", help="Write the diagnosis JSON here"),
    model_out: Optional[Path] = typer.Option(None, "--model-out", help="Write the extended model YAML"),
) -> None:
    """Show what the simulation gets wrong, name the cause, extend the model, measure the gain."""
    from aatest.diagnose.command import diagnose_command

    findings = diagnose_command(data, json_out, model_out)
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
    template: Optional[Path] = typer.Option(None, "--template", help="A lab's own template directory"),
    sign_key: Optional[Path] = typer.Option(None, "--sign-key"),
    pdf: bool = typer.Option(False, "--pdf", help="Also print the report to PDF (needs Chromium)"),
) -> None:
    """Re-render (and sign) the report of a run."""
    from aatest.engine.run import session

    typer.echo(f"report: {session.report(run_dir, template, sign_key, pdf)}")


@app.command()
@guarded
def keygen(
    keyfile: Path = typer.Argument(..., help="Private key file to create (public: KEYFILE.pub)"),
    passphrase: bool = typer.Option(False, "--passphrase", help="Ask for a passphrase"),
) -> None:
    """Create an Ed25519 signing key pair."""
    from aatest.engine.run import signing

    secret = typer.prompt("passphrase", hide_input=True, confirmation_prompt=True) if passphrase else None
    signing.generate_keypair(keyfile, secret)
    typer.echo(f"private key: {keyfile} (mode 0600)\npublic key:  {keyfile}.pub")


@app.command()
@guarded
def verify(
    report_file: Path = typer.Argument(..., help="Signed report"),
    public_key: Optional[Path] = typer.Option(None, "--public-key", help="Trusted public key"),
) -> None:
    """Check a signed report bundle: exit 0 untouched, 1 tampered or wrong key."""
    from aatest.engine.run import signing

    result = signing.verify_bundle(report_file, public_key)
    if result.ok:
        typer.echo(f"{report_file}: signature valid")
        return
    for reason in result.reasons:
        typer.echo(f"{report_file}: {reason}", err=True)
    raise typer.Exit(EXIT_FINDING)


@app.command()
@guarded
def schema(
    results: bool = typer.Option(False, "--results", help="The schema of results.json instead"),
) -> None:
    """Print the procedure JSON Schema (for editors), or with --results that of results.json."""
    from aatest.engine.procedure.schema_export import render

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
def station(
    host: str = typer.Option("127.0.0.1", "--host", help="Address to listen on (loopback default)"),
    port: int = typer.Option(8671, "--port"),
    records: Optional[str] = typer.Option(None, "--records", help="Records store URL for history"),
    token_file: Optional[Path] = typer.Option(
        None, "--token-file", help="Access token (≥ 32 characters; or AATEST_STATION_TOKEN)"
    ),
    runs: Path = typer.Option(Path("runs"), "--runs", help="Runs directory (new runs, history)"),
    lab: Optional[Path] = typer.Option(None, "--lab", help="Lab directory of procedure YAMLs"),
    rig: Optional[Path] = typer.Option(None, "--rig", help="Rig YAML (default: each procedure's)"),
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
    can_interface: Optional[str] = typer.Option(None, "--can-interface", help="python-can interface of the simulated CAN logger"),
    can_channel: Optional[str] = typer.Option(None, "--can-channel"),
) -> None:
    """Serve the simulated turntable over Modbus TCP (and its sensor logger on CAN)."""
    from aatest.twin.servers.modbus_server import serve_forever

    can_options = {k: v for k, v in (("can_interface", can_interface), ("can_channel", can_channel)) if v}
    serve_forever(host, port, seed, **can_options)


def main() -> None:
    app()


if __name__ == "__main__":
    main()
    sys.exit(0)
