"""The step loop: drive the rig through a plan, record each step atomically, resume in place.

Per recorded step: (re)establish the chamber set-point if needed, move to the start position,
start the motion and let it settle, start the DAQ (its trigger starts the table log), record,
stop the DAQ, bring the table to rest, then write the step's recording file atomically. A
static step longer than the table's log capacity is streamed instead (the DAQ delivers chunks
that are written as they arrive; the table logs its full-rate head:
:func:`execute_streamed_step`). A
fault at any point leaves the rig safe (see :mod:`aatest.engine.run.rig`) and keeps every step
completed so far; ``--resume`` continues with the first step not on disk.
"""

from __future__ import annotations

import hashlib
import logging
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, cast

from threadpoolctl import threadpool_limits

import aatest
from aatest.engine.errors import AatestError, AnalysisError, InputError, PluginError, RigFault
from aatest.engine.interfaces import (
    STREAM_CHUNK_S,
    StableChamber,
    StreamingDaq,
    TableEnvelope,
    soaks_until_stable,
    supports_streaming,
    table_capabilities,
)
from aatest.engine.logs import SampledLog
from aatest.engine.procedure.envelope import head_step, streams_record
from aatest.engine.run.events import RunEvents
from aatest.engine.run.progress import StepProgress
from aatest.engine.run.rig import Rig, running
from aatest.engine.run.run_state import RunState
from aatest.engine.run.status_poll import polling_status
from aatest.engine.run.writes import BackgroundWrites
from aatest.engine.simulation import SIMULATED_PARTS_KEY
from aatest.engine.steps import UNNAMED_SERIAL, Plan, PlannedStep
from aatest.recording.dataset import StepData

log = logging.getLogger("aatest.run")

DEFAULT_SOAK_S = 900.0
#: _ONE_BLAS_THREAD: the step loop runs BLAS single-threaded. Its products are thin (the twin's
#: tone sums are (rows × 4) @ (4 × 512), rotations 3 × 3 @ 3 × n): threads gain nothing on
#: them and, on a busy 2-core machine, each call waits for its threads to wake — the twin's
#: tone sum measured 4× the CPU time with OpenBLAS's threads (same results: no product is
#: split along its inner dimension).


def procedure_sha256(text: str) -> str:
    """Return the hex SHA-256 of the procedure text, which ties a run to its procedure."""
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def default_run_dir(procedure: str, root: Path = Path("runs")) -> Path:
    """Return ``root/<UTC time stamp>-<procedure>``, a fresh run directory name."""
    stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ")
    return root / f"{stamp}-{procedure}"


def _ask(events: RunEvents, step: PlannedStep, state: RunState) -> None:
    """Have the operator's instruction confirmed and record who confirmed it, and when."""
    if events.responder is None:
        raise InputError(f"step {step.id} has an operator prompt and nobody is set to answer it")
    events.observer.prompt_raised(step)
    answer = events.responder.answer(step)
    state.prompts_shown.append(step.id)
    state.prompt_answers.append(answer.as_json())


@dataclass
class _ChamberTracker:
    """Knows the set-point in force so a resumed run re-soaks before its next record."""

    setpoint_c: float | None = None
    soak_s: float = DEFAULT_SOAK_S
    #: the chamber step in force (its soak-until-stable criterion, if any)
    step: PlannedStep | None = None
    #: what each soak until stable achieved (``Stability.as_json`` with the set-point)
    stability: list[dict[str, float]] = field(default_factory=list)

    def ensure(self, rig: Rig, step: PlannedStep) -> None:
        target = step.temperature_c
        if step.kind == "chamber":
            self.soak_s = step.soak_s if step.soak_s is not None else DEFAULT_SOAK_S
            self.step = step
        if target is None or target == self.setpoint_c:
            return
        until = self.step if self.step is not None and self.step.soak_max_s is not None else None
        if until is not None and not soaks_until_stable(rig.chamber):  # refused by validate
            raise PluginError(f"chamber plugin {type(rig.chamber).__name__} cannot soak until "
                              "stable (no wait_until_stable); give soak_s instead")
        rig.chamber.set_temperature(target)
        if until is not None:
            self._until_stable(rig, until, target)
        else:
            rig.chamber.wait_stable(self.soak_s)
        # docs/method.md §4.2: switch the chamber off before recording (its fans and compressor
        # vibrate the table); the sensor then drifts slowly with its own thermal lag
        rig.chamber.off()
        self.setpoint_c = target


    def _until_stable(self, rig: Rig, step: PlannedStep, target: float) -> None:
        assert step.stable_tolerance_c is not None and step.stable_window_s is not None
        assert step.soak_max_s is not None
        chamber = cast(StableChamber, rig.chamber)  # checked by soaks_until_stable
        achieved = chamber.wait_until_stable(step.stable_tolerance_c, step.stable_window_s,
                                             step.soak_max_s)
        log.info("soak at %g °C: stable after %.0f s, sensor %.3f °C, spread %.3g °C over %g s "
                 "(tolerance %g °C)", target, achieved.waited_s, achieved.temperature_c,
                 achieved.spread_c, achieved.window_s, achieved.tolerance_c)
        self.stability.append({"setpoint_c": target, **achieved.as_json()})


#: the table serial of a plugin that reports none
UNREPORTED = "not reported by the plugin"


def identity_metadata(rig: Rig) -> dict[str, Any]:
    """The table's serial and the rig's declared capabilities, as the plugins report them now.

    Asked before ``start`` (what the plugins declare statically) and again once the rig is
    started, when a driver has identified its controller (model and serial). The serial comes
    from ``capabilities().serial``; a plugin without ``capabilities()`` may still offer the
    older ``serial`` attribute.
    """
    declared = table_capabilities(rig.turntable)
    serial = declared.serial if declared is not None else getattr(rig.turntable, "serial", None)
    plugin = rig.config.get("turntable", {}).get("plugin")
    turntable = {"plugin": plugin, "distribution": rig.versions.get(f"turntable:{plugin}"),
                 "declared": declared.model_dump(mode="json") if declared is not None else None}
    return {"table_serial": str(serial or UNREPORTED),
            "rig": {**rig.config, "capabilities": {"turntable": turntable}}}


def run_metadata(
    plan: Plan, rig: Rig, procedure_text: str, seed: int, operator: str
) -> dict[str, Any]:
    """Everything that makes a recording traceable, stored in the recording itself."""
    return {
        "operator": operator,
        "procedure": plan.procedure,
        "standard": plan.standard,
        "procedure_text": procedure_text,
        "procedure_sha256": procedure_sha256(procedure_text),
        **identity_metadata(rig),
        "plugin_versions": rig.versions,
        "seed": seed,
        "sensor": plan.sensor.model_dump(),
        "sensors": [s.model_dump(mode="json") for s in rig.sensor_infos()],
        "aatest_version": aatest.__version__,
        "started_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        "plan": [s.model_dump(mode="json") for s in plan.steps],
        "analysis": list(plan.analysis),
    }


def execute_step(rig: Rig, step: PlannedStep) -> tuple[Any, Any]:
    """Run one recorded step on the rig; return (table log, DAQ log)."""
    rig.turntable.move_to(step.inner_deg, step.outer_deg)
    rig.turntable.begin_motion(step)
    rig.daq.start_logging(step)
    table = rig.turntable.record(step)
    daq = rig.daq.stop_logging()
    rig.turntable.end_motion()
    return table, daq


def check_step_sync(step: PlannedStep, table: SampledLog, daq: SampledLog) -> Any:
    """Fail the run at a step whose loggers cannot be synchronised, not after the whole run.

    Cheap: the installed ``sync`` analysis (its ``check_step``) reads the pulses, the trigger
    and the time stamps only (no channel is resampled). The step is already handed to the
    recorder (data is never lost). Found through its entry point like every analysis, so the
    engine does not depend on the synchronisation package. Returns what ``check_step``
    returns (the shipped one: the step's clock relation; None without a check).

    Raises
    ------
    RigFault
        Naming the step and why its freeze-pulse edges do not synchronise (exit 3).
    """
    from aatest.engine import registry

    check = getattr(registry.load("analysis", "sync").target, "check_step", None)
    if check is None:  # a replacement sync analysis without the run-time check
        return None
    try:
        return check(StepData(step=step, table=table, daq=daq))
    except AnalysisError as exc:
        raise RigFault(f"{exc} — the loggers cannot be synchronised (checked as the step was "
                       f"recorded; the step is kept in the recording)") from exc


def _checked(recorder: Any, step: PlannedStep, checked: Any) -> None:
    """Hand what the run-time check returned to a recorder that takes it (``step_checked``:
    :mod:`aatest.early.analysis` passes the step's clock relation to its child, which then
    does not fit it again)."""
    step_checked = getattr(recorder, "step_checked", None)
    if step_checked is not None:
        step_checked(step, checked)


def _synchronises(plan: Plan) -> tuple[bool, bool]:
    """(named, required): whether ``sync`` is named in the plan's analysis, and whether a
    named analysis requires it. Most analyses read both logs and require it; ``drift`` reads
    the DAQ's alone, so a drift-only record is never held to the freeze pulse. When the
    requirements cannot be resolved (an analysis not installed: the loader said so), any
    named analysis counts as requiring it."""
    from aatest.engine.analysis import passes

    names = {a if isinstance(a, str) else next(iter(a), "") for a in plan.analysis}
    if not names:
        return False, False
    try:
        ordered = passes.order(passes.requested_names(plan.analysis))
    except AatestError:
        return "sync" in names, True
    return "sync" in names, any(p.name == "sync" for p in ordered)


def _syncs(synchronised: tuple[bool, bool], table: SampledLog, daq: SampledLog) -> bool:
    """Whether the run checks this step's synchronisation as it is recorded: ``sync`` is
    named, or a named analysis requires it and both loggers recorded the pulse."""
    named, required = synchronised
    pulses = "sync_pulse" in table.channels and "sync_pulse" in daq.channels
    return named or (required and pulses)


def execute_streamed_step(rig: Rig, step: PlannedStep, recorder: Any, events: RunEvents,
                          chunk_s: float = STREAM_CHUNK_S) -> tuple[SampledLog, SampledLog]:
    """Record one long static step with the DAQ streaming: each chunk goes to the recording as
    it arrives (memory: one chunk of ``chunk_s`` lab seconds), the table logs at full rate
    as long as its buffer holds (:func:`head_step`: the freeze-pulse edges sync is fitted on).

    Order: position, settle, then the DAQ streams (its trigger starts the table's
    log), then the table's log is collected and the step file written atomically. A fault or
    an abort mid-record leaves the chunks received in the step's ``.partial`` spool (named in
    the message); the step itself is not complete, so ``--resume`` records it again.
    Returns the table log and the last DAQ chunk (for the observer).
    """
    rig.turntable.move_to(step.inner_deg, step.outer_deg)
    rig.turntable.begin_motion(step)
    streamed = recorder.stream_step(step)
    last: SampledLog | None = None
    try:
        daq = cast(StreamingDaq, rig.daq)  # checked by _streamed (supports_streaming)
        for chunk in daq.stream_logging(step, chunk_s):
            streamed.add(chunk)
            last = chunk
            events.observer.step_chunk(step, chunk)
            events.abort.check()
        table = rig.turntable.record(head_step(step, _envelope(rig)))
        rig.turntable.end_motion()
        if last is None:
            raise RigFault(f"step {step.id}: the DAQ streamed no samples")
        streamed.finish(table)
    except AatestError as exc:
        kept = streamed.abandon()
        seconds = streamed.spool.duration_s
        raise _with_note(exc, f"step {step.id}: the {seconds:.0f} s of DAQ samples recorded "
                              f"before this are kept in {kept}; `aatest run --resume` records "
                              "the step again") from exc
    except BaseException:
        streamed.abandon()
        raise
    return table, last


def _streamed(rig: Rig, step: PlannedStep) -> bool:
    """True when ``step`` is a long static record and the rig's DAQ streams it."""
    if step.kind != "static" or not supports_streaming(rig.daq):
        return False
    return streams_record(step, _envelope(rig))


def _envelope(rig: Rig) -> TableEnvelope:
    """The table's envelope with the DAQ's streaming capability (as the planner saw it)."""
    return rig.turntable.envelope().model_copy(
        update={"streaming_daq": supports_streaming(rig.daq)})


def _with_note(exc: AatestError, note: str) -> AatestError:
    """The same error (type, exit code) with a sentence added, when its type allows it."""
    try:
        noted = type(exc)(f"{exc}; {note}")
    except TypeError:  # an error type with structured arguments: keep it as it is
        return exc
    return noted


@contextmanager
def _closing(writes: BackgroundWrites) -> Iterator[None]:
    """Finish the write in flight before the rig's safe stop and close (an exit of the
    ``with`` in any way)."""
    try:
        yield
    except BaseException:
        writes.close(raising=False)
        raise
    writes.close()


def declare_simulation(plan: Plan, rig: Rig, recorder: Any) -> list[str]:
    """Record which parts of the started rig are simulated (``metadata.simulated_parts``,
    joined with those of earlier sessions of a resumed run: a run partly recorded on a
    simulator stays a simulation) and refuse, before any motion, to calibrate an unnamed unit
    on a real rig (InputError, exit 2). Returns the simulated parts."""
    meta = recorder.run_metadata
    parts = sorted({*(meta.get(SIMULATED_PARTS_KEY) or []), *rig.simulated_parts()})
    recorder.amend_run_metadata({SIMULATED_PARTS_KEY: parts})
    recorded = str((meta.get("sensor") or {}).get("serial") or UNNAMED_SERIAL)  # a resumed run
    if UNNAMED_SERIAL not in (recorded, plan.sensor.serial) and recorded != plan.sensor.serial:
        raise InputError(f"this run records unit {recorded!r}; it cannot be resumed as "
                         f"{plan.sensor.serial!r}")
    if not parts and UNNAMED_SERIAL == recorded == plan.sensor.serial:
        raise InputError(
            f"procedure {plan.procedure!r}: no unit serial for a calibration on a real rig; "
            "name the unit with `aatest run --serial SN` (or AATEST_SERIAL) or in the "
            "procedure's sensor.serial")
    return parts


def run_plan(
    plan: Plan,
    rig: Rig,
    recorder: Any,
    state: RunState,
    run_dir: Path,
    show_progress: bool = True,
    events: RunEvents | None = None,
    on_started: Callable[[Rig], None] | None = None,
) -> None:
    """Execute every step not yet recorded; persist progress after each one.

    ``events`` carries the observer, the prompt responder and the abort flag
    (:mod:`aatest.engine.run.events`); an abort ends like a fault, in the rig's safe stop.
    ``on_started`` is called once the rig has started, before the first step (the session
    records the table's identity then).
    """
    events = events or RunEvents()
    done = set(recorder.completed_step_ids()) | set(state.chamber_steps_done)
    chamber = _ChamberTracker(stability=state.soak_stability)
    started = time.perf_counter()
    writes = BackgroundWrites(recorder)  # a step's file is written while the next records
    synchronised = _synchronises(plan)  # what each recorded step is checked for
    try:
        with running(rig), StepProgress(plan, done, enabled=show_progress) as progress, \
                threadpool_limits(limits=1, user_api="blas"), _closing(writes):
            if on_started is not None:
                on_started(rig)
            declare_simulation(plan, rig, recorder)  # started, nothing moved yet
            events.observer.run_started(plan, frozenset(done))
            for step in plan.steps:
                if step.id in done:
                    chamber.soak_s = step.soak_s or chamber.soak_s
                    continue
                events.abort.check()
                progress.begin(step)
                events.observer.step_started(step)
                if step.prompt and step.id not in state.prompts_shown:
                    _ask(events, step, state)
                    events.abort.check()
                chamber.ensure(rig, step)
                if step.kind == "chamber":
                    state.chamber_steps_done.append(step.id)
                elif _streamed(rig, step):
                    writes.wait()  # the recorder serves one writer at a time
                    with polling_status(rig.turntable, step, events.observer):
                        table, last = execute_streamed_step(rig, step, recorder, events)
                    events.observer.step_samples(step, table, last)
                else:
                    with polling_status(rig.turntable, step, events.observer):
                        table, daq = execute_step(rig, step)
                    events.observer.step_samples(step, table, daq)
                    events.abort.check()  # aborted while recording: the step is not kept
                    writes.submit(step, table, daq)
                    if _syncs(synchronised, table, daq):
                        _checked(recorder, step, check_step_sync(step, table, daq))
                state.save(run_dir)
                progress.end(step)
                events.observer.step_finished(step)
            writes.wait()
        events.observer.run_finished()
    except AatestError as exc:
        events.observer.run_stopped(str(exc))
        raise
    finally:
        state.wall_duration_s += time.perf_counter() - started
        state.save(run_dir)
