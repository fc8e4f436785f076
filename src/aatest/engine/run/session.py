"""What each CLI command does, end to end, without any CLI concerns.

procedure → plan → envelope → rig → runner → recording → analyses → uncertainty → verdicts →
results → report → signature
"""

from __future__ import annotations

import contextlib
import inspect
import logging
import os
import sys
import threading
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from aatest.bundle import observers as bundle_observers
from aatest.bundle import signing
from aatest.bundle.signing_key import PASSPHRASE_ENV, signing_key, signing_problems
from aatest.engine import registry
from aatest.engine.analysis.passes import AnalysisResults, run_analyses
from aatest.engine.analysis.results_file import (
    RESULTS_FILE,
    build_results,
    read_results,
    results_json,
    write_results,
)
from aatest.engine.errors import AatestError, InputError, ProcedureError
from aatest.engine.interfaces import PdfRenderer
from aatest.engine.procedure.models import Acceptance
from aatest.engine.run.events import ConfirmPrompts, RunEvents, terminal_responder
from aatest.engine.run.rig import Rig, build_rig
from aatest.engine.run.run_state import STATE_FILE, RunState, open_state, run_lock
from aatest.engine.run.runner import (
    UNREPORTED,
    default_run_dir,
    identity_metadata,
    procedure_sha256,
    run_metadata,
    run_plan,
)
from aatest.engine.simulation import KIND_KEY, kind_of, metadata_of
from aatest.engine.steps import Plan, SensorRef
from aatest.presentation.figures import drawing_aside, ready_to_draw
from aatest.recording.dataset import Dataset
from aatest.results import RunResults
from aatest.results.root import Signature
from aatest.run_operator import default_operator
from aatest.storage import RemotePath, Where

if TYPE_CHECKING:
    from aatest.early.analysis import EarlyResults, EarlyRun

log = logging.getLogger("aatest")

#: how a run's prompts were confirmed (results metadata ``confirm_prompts``)
PromptMode = Literal["ask", "auto", "station"]


@dataclass(frozen=True)
class UnitName:
    """The unit named at run time (``aatest run --serial SN [--model M]``, ``AATEST_SERIAL``)."""

    serial: str | None = None
    model: str | None = None

    def apply(self, sensor: Any) -> Any:
        """The procedure's ``sensor`` with the serial (and model) given here."""
        update = {k: v for k, v in (("serial", self.serial), ("model", self.model)) if v}
        return sensor.model_copy(update=update)


@dataclass
class Prepared:
    """A validated procedure ready to run: its text, plan and rig configuration."""

    path: Path
    text: str
    plan: Plan
    rig_config: Any
    expansion: Any
    #: per listed analysis, the steps it will use (its requirements are met)
    coverage: Any = None
    #: the turntable's envelope (``streaming_daq`` set) and the DAQ's channels, for preflight
    envelope: Any = None
    daq_channels: tuple[str, ...] = ()
    #: the parsed procedure (with its source tree, for located preflight problems)
    procedure: Any = None

    def plan_json(self) -> dict[str, Any]:
        """``aatest plan --json``: the steps, lab duration and the points out of envelope."""
        return dict(self.expansion.to_contract_json())


@registry.pinned()  # the installed plugins are read once (preflight prepares outside a run)
def prepare(procedure: Path, rig_file: Path | None, unit: UnitName | None = None) -> Prepared:
    """Load, expand and envelope-check a procedure; nothing moves.

    ``unit`` names the unit at run time (``run --serial/--model``): a procedure is a template
    for every unit of its model, so its ``sensor.serial`` may be omitted.
    """
    from aatest.engine.analysis.coverage import check_coverage
    from aatest.engine.procedure.envelope import check_envelope
    from aatest.engine.procedure.loader import load_rig, parse_procedure, rig_from_procedure
    from aatest.engine.procedure.planner import expand_traced
    from aatest.positioned_yaml import read_text

    text = read_text(procedure)  # read once: the hash recorded is of exactly what was planned
    proc = parse_procedure(text, str(procedure))
    if unit is not None:
        proc = proc.model_copy(update={"sensor": unit.apply(proc.sensor)})
    rig_config = load_rig(rig_file) if rig_file else rig_from_procedure(proc)
    sensor = SensorRef(model=proc.sensor.model, serial=proc.sensor.serial)
    envelope, datasheet, channels = _declared_limits(rig_config, sensor)
    expansion = expand_traced(proc, envelope=envelope, datasheet=datasheet)
    check_envelope(expansion.plan, envelope, datasheet, procedure_file=str(procedure),
                   sources=expansion.sources)
    coverage = check_coverage(proc, expansion.plan, dict(expansion.sources),
                              rig_config.chamber.plugin, datasheet)
    return Prepared(procedure, text, expansion.plan, rig_config, expansion, coverage, envelope,
                    channels, proc)


def _declared_limits(rig_config: Any, sensor: SensorRef) -> tuple[Any, Any, tuple[str, ...]]:
    """The turntable plugin's envelope, the sensor's datasheet and the DAQ's channels.

    The rig is only constructed (no plugin connects in its constructor) and never started, so
    nothing here reaches the hardware: no ``start``, no ``safe_stop`` and no ``close`` — a
    ``close`` that stops the table would otherwise stop a table another run is using whenever
    someone validates a procedure (docs/vendor-plugins.md, "Life cycle").
    """
    from aatest.engine.errors import PluginError
    from aatest.engine.interfaces import daq_refusal, supports_streaming

    rig = build_rig(rig_config, sensor, seed=0)
    refusal = daq_refusal(rig.daq, rig.turntable)
    if refusal:  # e.g. the simulated DAQ beside a real table: refused before anything moves
        raise PluginError(f"daq plugin {rig_config.daq.plugin!r} cannot record beside turntable "
                          f"plugin {rig_config.turntable.plugin!r}: {refusal}")
    # long static records need a streaming DAQ (docs/interfaces.md §3)
    envelope = rig.turntable.envelope().model_copy(
        update={"streaming_daq": supports_streaming(rig.daq)})
    return envelope, rig.datasheet, tuple(rig.daq.channels())


@registry.pinned()  # the installed plugins are read once for the analysis
def analyse_and_report(  # noqa: PLR0913 - the options of `aatest analyze`/`run` one to one
    data_path: Where,
    out_dir: Where,
    template: str | None = None,
    template_dir: Path | None = None,
    key_path: Path | None = None,
    *,
    lab_duration_s: float | None = None,
    wall_duration_s: float | None = None,
    pdf: bool = False,
    extra_metadata: dict[str, Any] | None = None,
    early: EarlyResults | None = None,
) -> RunResults:
    """Read a recording/import, run its analyses, write results.json and the signed report;
    return the typed results (what report plugins read).

    ``lab_duration_s`` (s) defaults to the sum of the recorded steps' lab time, and
    ``wall_duration_s`` (s) to 0 for imported data that has no run behind it; both are
    reported so the lab-time-to-wall-time ratio of a run stays on record.
    ``extra_metadata`` is merged into the results metadata (e.g. who confirmed each prompt).
    ``early``: the per-step analysis ``aatest run`` made while recording
    (:mod:`aatest.early.analysis`); the pass takes what is of the same data.
    ``data_path`` and ``out_dir`` may be on object storage (docs/storage.md): the recording
    is streamed, and the files written are uploaded there.
    """
    from aatest.recording import read_dataset

    # the analyses' figures drawn aside, from now until the results take them
    with drawing_aside():
        data = read_dataset(data_path)
        if early is not None:
            early.offer(data)
        requested = list(data.metadata.get("analysis", []))
        analysis = run_analyses(data, requested)
        lab = lab_duration_s if lab_duration_s is not None else sum(
            s.step.lab_duration_s for s in data.steps
        )
        report_name = template or data.metadata.get("report_template") or \
            "calibration-certificate"
        # the report prepared from here, its recording hashed (a local run directory) meanwhile
        with report_prepared(report_name, out_dir if isinstance(out_dir, Path) else None):
            results = decided_results(data, analysis, lab, wall_duration_s or 0.0,
                                      extra_metadata)
            out_dir.mkdir(parents=True, exist_ok=True)
            render_and_sign(results, out_dir, report_name, template_dir, key_path, pdf)
    return results


def decided_results(data: Dataset, analysis: AnalysisResults, lab_duration_s: float,
                    wall_duration_s: float, extra_metadata: Mapping[str, Any] | None = None
                    ) -> RunResults:
    """The typed results of an analysis pass (lab and wall time in s), marked with their
    kind (a simulation is never a calibration), with uncertainty budgets, verdicts and,
    last, the analyses' figures.

    Why the figures last: they are drawn aside meanwhile (:func:`aatest.presentation.figures.
    drawn`), and nothing before needs them; the budgets and verdicts of the stepped sine
    take ≈ 0.2 s, the figures ≈ 0.85 s of CPU with matplotlib's import.
    """
    results = build_results(data, analysis, lab_duration_s, wall_duration_s, figures=False)
    for key, value in (extra_metadata or {}).items():
        setattr(results.metadata, key, value)
    setattr(results.metadata, KIND_KEY, kind_of(metadata_of(results)))  # never a calibration
    results = decide(results, data)
    results.figures = analysis.figures
    return results


def report_prepared(template: str, run_dir: Path | None = None
                    ) -> contextlib.AbstractContextManager[Any]:
    """The report plugin's optional ``preparing()`` (see :func:`_render`) around the whole
    report phase: results, uncertainty and verdicts, then the render, so what the plugin starts
    there overlaps all of that work (given the local ``run_dir`` the report goes to, what it
    prepares of that directory too: the HTML reports hash its recording). A plugin that does
    not load prepares nothing here (the render then says why it cannot run).
    """
    try:
        reporter = _reporter(template)
    except AatestError:
        return contextlib.nullcontext()
    return _preparing(reporter, run_dir)


def _reporter(template: str) -> Any:
    """The report plugin ``template``, configured (raises when it does not load)."""
    info = registry.load("report", template)
    return info.target(registry.configure(info, {}))


def _preparing(reporter: Any, run_dir: Path | None = None
               ) -> contextlib.AbstractContextManager[Any]:
    """The plugin's optional ``preparing()`` context, or one that does nothing; given the
    ``run_dir`` it will render into, when its ``preparing`` takes one (``run_dir=``)."""
    preparing = getattr(reporter, "preparing", None)
    if not callable(preparing):
        return contextlib.nullcontext()
    takes_run_dir = run_dir is not None and "run_dir" in inspect.signature(preparing).parameters
    prepared: contextlib.AbstractContextManager[Any] = (
        preparing(run_dir=run_dir) if takes_run_dir else preparing())
    return prepared


def acceptance_of(metadata: Mapping[str, Any]) -> Acceptance:
    """The procedure's acceptance, from the procedure text stored in the recording.

    Imported data has no procedure: the default (simple rule, datasheet limits) applies.
    """
    from aatest.engine.procedure.loader import parse_procedure

    text = metadata.get("procedure_text")
    if not text:
        return Acceptance()
    source = f"{metadata.get('recording', 'recording')} (procedure_text)"
    return parse_procedure(str(text), source).acceptance


def decide(results: RunResults, data: Dataset) -> RunResults:
    """The engine's decisions, after the analyses: uncertainty budgets, then verdicts.

    Both stages fill fields of the typed results (validated on assignment, so a stage
    writing a value the models do not allow is an error, not a silent extra).
    """
    from aatest.engine.analysis.plugins import installed_analyses, listed_analyses
    from aatest.engine.run.rig import datasheets
    from aatest.metrology.uncertainty import apply_uncertainty
    from aatest.metrology.verdicts import apply_verdicts

    apply_uncertainty(results, data=data)
    return apply_verdicts(results, datasheets(data.metadata, data.sensors),
                          acceptance_of(data.metadata),
                          listed_analyses(list(data.metadata.get("analysis", []))),
                          installed_analyses())


def render_and_sign(
    results: RunResults,
    run_dir: Where,
    template: str,
    template_dir: Path | None,
    key_path: Path | None,
    pdf: bool = False,
) -> Where:
    """Write results.json, render the report (and its PDF), sign the bundle when a key is set.

    ``results`` is the typed record: written once as results.json, handed to the report
    plugin as it is. A ``run_dir`` on object storage gets its files rendered locally and
    uploaded (:func:`aatest.storage.staged`), then is signed in place.
    """
    from aatest.storage import publish, published, staged

    private = None
    if key_path is not None:
        private = signing.load_private_key(key_path, os.environ.get(PASSPHRASE_ENV))
        fingerprint = signing.key_fingerprint(private.public_key())
        results.signature = Signature(fingerprint=fingerprint)
    # e.g. a certificate number, before results are written
    bundle_observers.before_signing(results)
    with staged(run_dir) as local_dir:
        local_report = _render(results, local_dir, template, template_dir, pdf)
    report = published(local_report, local_dir, run_dir)
    if private is not None:
        signing.sign_bundle(report, private)
    report = publish(report)  # `run --out URL`: the finished bundle goes up, then is registered
    bundle_observers.after_signing(results, report)
    return report


def _render(results: RunResults, run_dir: Path, template: str, template_dir: Path | None,
            pdf: bool) -> Path:
    """results.json and the report plugin's files (and PDF) in the local ``run_dir``.

    A report plugin may prepare its render while results.json is written (its optional
    ``preparing()``, a context manager, given ``run_dir=`` when it takes it: the HTML reports
    start their confined render process there, whose imports then overlap this process's
    work, and hash the recording on a thread meanwhile).
    """
    try:
        reporter = _reporter(template)
    except AatestError:
        write_results(results, run_dir)  # the results stand even when the report cannot
        raise
    with _preparing(reporter, run_dir), _results_written(results, run_dir, reporter):
        if pdf and not isinstance(reporter, PdfRenderer):
            raise InputError(f"report '{template}' cannot print a PDF (its plugin has no "
                             "render_pdf); run without --pdf or choose another report")
        report: Path = reporter.render(results, run_dir, template_dir)
    if pdf and isinstance(reporter, PdfRenderer):
        reporter.render_pdf(report)
    return report


@contextlib.contextmanager
def _results_written(results: RunResults, run_dir: Path, reporter: Any) -> Iterator[None]:
    """results.json written by the end of the block: on a thread while the block renders, for
    a report plugin that renders from the typed record alone (``renders_from_record``),
    else before the block.

    Why: writing results.json (the figures' SVG inside, indented: Python's own JSON
    encoder) took ≈ 0.24 s of the stepped sine's report phase, while this process mostly
    waits for the confined render child. The document is taken from ``results`` here, before
    the block, so the thread writes its own copy (the same bytes as :func:`write_results` of
    ``results``). The thread ends with the block, which then raises its error if it had one:
    the results stand even when the report cannot.
    """
    if getattr(reporter, "renders_from_record", False) is not True:
        write_results(results, run_dir)
        yield
        return
    document = results_json(results)
    failed: list[BaseException] = []

    def write() -> None:
        try:
            write_results(document, run_dir)
        except BaseException as exc:  # noqa: BLE001 - raised by the block's end, below
            failed.append(exc)

    thread = threading.Thread(target=write, name="aatest-results-json", daemon=True)
    thread.start()
    try:
        yield
    finally:
        thread.join()
        if failed:
            raise failed[0]


@registry.pinned()  # the installed plugins are read once per run
def run(  # noqa: PLR0913 - the options of `aatest run` one to one, the later ones by keyword
    procedure: Path,
    rig_file: Path | None,
    out_dir: Where | None,
    resume: bool,
    seed: int,
    key_path: Path | None,
    show_progress: bool = True,
    *,
    operator: str | None = None,
    pdf: bool = False,
    events: RunEvents | None = None,
    confirm_prompts: ConfirmPrompts = "ask",
    unit: UnitName | None = None,
    prepared: Prepared | None = None,
) -> tuple[Where, RunResults]:
    """``aatest run``: execute (or resume) a procedure and produce its results and report.

    ``prepared`` is the procedure as the preflight (:mod:`aatest.preflight`) checked it;
    without it the procedure is prepared here and its plan-level preflight (report template,
    analysable steps, disk space) runs before anything moves.

    ``events`` lets a caller (the station) observe, answer prompts and abort; without a
    responder the terminal answers, and without a terminal the run is refused before the rig
    moves unless ``confirm_prompts`` is ``"auto"`` (see :func:`events.terminal_responder`).
    How prompts were confirmed is recorded in the results metadata as ``confirm_prompts``
    (``ask``: a person at the terminal, ``auto``: unattended, ``station``: the caller's
    responder, i.e. the operator's station), beside ``prompt_answers`` (who, when, how).
    ``unit`` names the unit calibrated (else the procedure's ``sensor``); a calibration of an
    unnamed unit on a real rig is refused once the rig started, before it moves (exit 2).
    An ``out_dir`` on object storage is recorded in a local staging directory and uploaded
    once finished (:mod:`aatest.storage.staging`); the URL is returned.
    """
    if isinstance(out_dir, RemotePath):
        return _run_to_url(out_dir, lambda local: run(
            procedure, rig_file, local, resume, seed, key_path, show_progress,
            operator=operator, pdf=pdf, events=events, confirm_prompts=confirm_prompts,
            unit=unit, prepared=prepared))
    checked = prepared is not None
    prepared = prepared or prepare(procedure, rig_file, unit)
    plan = prepared.plan
    if (key := signing_key(key_path)) is not None:  # a bad or too open key fails before any motion
        signing.load_private_key(key, os.environ.get(PASSPHRASE_ENV))
    elif unsigned := signing_problems(prepared.procedure, None):  # asked for, cannot be
        raise ProcedureError(unsigned)  # given: refused before the rig moves
    if out_dir is None:
        if resume:
            raise InputError("--resume needs --out RUN_DIR (the run to continue)")
        out_dir = default_run_dir(plan.procedure)
    if not checked:
        from aatest.engine.plan_checks import refuse_unrunnable

        refuse_unrunnable(prepared, out_dir)
    if resume:
        seed = RunState.load(out_dir).seed
    events = events or RunEvents()
    mode: PromptMode = "station" if events.responder is not None else confirm_prompts
    if events.responder is None:
        shown = RunState.load(out_dir).prompts_shown if resume else []
        events.responder = terminal_responder(
            plan, shown, operator or default_operator(), confirm_prompts,
            sys.stdin is not None and sys.stdin.isatty(),
        )
    with run_lock(out_dir):  # a second run on this directory exits 2, naming this one
        return _run_locked(_RunRequest(prepared, out_dir, resume, seed, key_path, show_progress,
                                       operator, pdf, events, mode))


def _run_to_url(url: RemotePath, run_local: Any) -> tuple[Where, RunResults]:
    """Run into the URL's staging directory, upload the finished bundle, then drop the
    staging copy; an interrupted run stays there for ``--resume --out URL``."""
    import shutil

    from aatest.storage import publishing, staging_dir

    url.mkdir()  # a missing bucket is refused before anything moves
    local = staging_dir(url)
    with publishing(local, url):
        _, results = run_local(local)
    shutil.rmtree(local, ignore_errors=True)  # every file is on the store now
    return url, results


@dataclass(frozen=True)
class _RunRequest:
    """What :func:`run` resolved, handed to the part that runs under the directory lock."""

    prepared: Prepared
    out_dir: Path
    resume: bool
    seed: int
    key_path: Path | None
    show_progress: bool
    operator: str | None
    pdf: bool
    events: RunEvents
    prompt_mode: PromptMode


def _run_locked(request: _RunRequest) -> tuple[Path, RunResults]:
    """The body of :func:`run`, executed while holding the run directory's lock."""
    from aatest.early.analysis import early_analysis
    from aatest.recording import RunRecorder

    prepared, out_dir, resume, seed = (request.prepared, request.out_dir, request.resume,
                                       request.seed)
    operator, events = request.operator, request.events
    plan = prepared.plan
    sha = procedure_sha256(prepared.text)
    state = open_state(out_dir, plan.procedure, sha, seed, resume)
    recorder = RunRecorder(out_dir)
    # the figures' processes, started at the record phase's end (finish_recording), draw
    # until the report takes the figures (analyse_and_report's block is this one)
    with drawing_aside():
        early_results: EarlyResults | None = None
        if not state.finished:  # a finished run that is "resumed" is only analysed again
            rig = build_rig(prepared.rig_config, plan.sensor, seed)
            if not resume:
                meta = run_metadata(plan, rig, prepared.text, seed, operator or default_operator())
                meta["report_template"] = plan.report_template
                recorder.write_run_metadata(meta)  # before start: a failed start can be resumed
            # the analysis pass's per-step work is made while the rig records (a child process)
            with early_analysis(plan, recorder, prepared.envelope) as early:
                run_plan(plan, rig, early.recorder, state, out_dir,
                         show_progress=request.show_progress, events=events,
                         on_started=lambda started: _identify(recorder, started))
                early_results = finish_recording(recorder, early)
            state.finished = True
            state.save(out_dir)
        # only now, with every step inside recording.mcap, the per-step copies can go
        recorder.prune_step_files()
        key = signing_key(request.key_path)  # one asked for is there (run() checked)
        results = analyse_and_report(
            out_dir, out_dir, plan.report_template, None, key,
            lab_duration_s=plan.lab_duration_s, wall_duration_s=state.wall_duration_s,
            pdf=request.pdf,
            extra_metadata={"prompt_answers": state.prompt_answers,
                            "confirm_prompts": request.prompt_mode,
                            **({"soak_stability": state.soak_stability} if state.soak_stability
                               else {})},
            early=early_results,
        )
    return out_dir, results


def finish_recording(recorder: Any, early: EarlyRun) -> EarlyResults | None:
    """The end of the record phase: the step files merged into ``recording.mcap``, its
    SHA-256 begun on a thread (:func:`aatest.bundle.manifest.hash_soon`: the report's
    traceability and the signature read it; the analysis's first forking map joins the
    thread first), and what the early analysis made, its child reaped.

    Then, when the early analysis made everything it was sent (the pass will only take its
    work, and asks for its first figures within a fraction of a second:
    :attr:`~aatest.early.analysis.EarlyResults.complete`), the figures' processes are started
    inside the open :func:`~aatest.presentation.figures.drawing_aside` block (that of
    :func:`_run_locked`): no thread runs here between the early analysis's end and the
    hashing's start, and matplotlib's import (≈ 0.4 s of CPU) then overlaps the pass
    instead of delaying the first figure (bench/end_to_end.py). Not before the merge: the
    early analysis's child, at a lower priority, still makes its last work there (the
    transfer function's last fits were lost to them). Not when the child was still at work
    (a loaded machine): the pass then fits the last group itself on both cores, which the
    processes' import slowed (analyse 0.20 → 0.51 s, median of 7). Not without an early
    analysis (a long static record, streamed): the pass takes seconds before its first
    figure, and the processes, forked from this process as the record left it, would hold
    its memory meanwhile (bench/long_record.py --minutes 60: 292 → 322 MB).
    """
    from aatest.bundle.manifest import hash_soon
    from aatest.parallel.forked import join_before_fork

    recording = recorder.finalize()
    made = early.results()
    if made is not None and made.complete:
        ready_to_draw()
    hashing = hash_soon(recording)
    if hashing is not None:
        join_before_fork(hashing)
    return made


def _identify(recorder: Any, started: Rig) -> None:
    """Record the table's identity once the rig has started (a driver identifies its
    controller in ``start``): its serial and declared capabilities join the run metadata.

    A resumed run must go on on the table it was recorded on: a table that identifies with
    another serial is a :class:`RigFault` (exit 3, the rig is then stopped and closed).
    """
    from aatest.engine.errors import RigFault
    from aatest.recording.writer import load_run_metadata

    recorded = load_run_metadata(recorder.steps_dir)
    identity = identity_metadata(started)
    before, now = recorded.get("table_serial"), identity["table_serial"]
    if UNREPORTED not in (before, now) and before not in (None, now):
        raise RigFault(f"the table identifies as serial {now!r}, but this run was recorded on "
                       f"{before!r}: resume it on that table")
    rig = {**(recorded.get("rig") or {}), "capabilities": identity["rig"]["capabilities"]}
    recorder.write_run_metadata({**recorded, "table_serial": now, "rig": rig})


def report(
    run_dir: Where, template_dir: Path | None, key_path: Path | None, pdf: bool = False
) -> Where:
    """``aatest report``: re-render (and re-sign) from an existing results.json.

    A results.json written before the engine decided verdicts (schema version 1, no
    ``verdicts`` key) is refused with InputError (exit 2): rendering it would print a
    certificate without pass/fail, and the report never decides verdicts itself.
    """
    results = read_results(run_dir)
    if "verdicts" not in results.model_fields_set:
        raise InputError(
            f"{run_dir / RESULTS_FILE}: no 'verdicts' (schema_version {results.schema_version}, "
            "written before the engine decided verdicts); regenerate it with "
            f"`aatest analyze {run_dir}`, then run `aatest report` again"
        )
    results.signature = None
    template = results.metadata.report_template or "calibration-certificate"
    stale_pdf = run_dir / "report.pdf"
    if not pdf and stale_pdf.exists():
        stale_pdf.unlink()  # it shows the old report; a new signature must not cover it
    return render_and_sign(results, run_dir, template, template_dir, signing_key(key_path), pdf)


def run_wall_duration(run_dir: Where) -> float | None:
    """Wall-clock time (s) the run in ``run_dir`` has taken so far, None without a run state.

    ``aatest analyze`` of a run directory reports it beside the lab time, so the ratio of lab
    time to wall time stays visible after the run; imported data has no run state.
    """
    return RunState.load(run_dir).wall_duration_s if (run_dir / STATE_FILE).exists() else None
