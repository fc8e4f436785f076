"""One run at a time, driven from the page: start, resume, answer prompts, abort.

The run itself is exactly ``aatest run`` (:func:`aatest.engine.run.session.run`) in a worker
thread, after the same preflight and reference-standard check (a start they refuse is answered
with all their problems; nothing is built or moved), with the station's observer, responder
and abort flag plugged into its events: the unit named on the page is passed as
``--serial``/``--model`` would be (an unnamed unit on a real rig is refused by the engine
before anything moves), and the report is signed with the station's key as ``--sign-key``
would (the key is the station's configuration, never the browser's). The latest state is kept
as a snapshot so a browser that connects mid-run sees the same page.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from aatest.engine.errors import AatestError, InputError
from aatest.engine.run.events import AbortFlag, RunEvents
from aatest.engine.run.rig import sensor_datasheet
from aatest.engine.run.runner import default_run_dir
from aatest.engine.run.session import UnitName
from aatest.station.catalogue import History, Procedures, present_files, results_summary
from aatest.station.live import Publish, StationObserver, StationResponder
from aatest.storage import RemotePath


@dataclass
class Snapshot:
    """What a newly connected browser needs to draw the current run."""

    run: dict[str, Any] = field(default_factory=dict)
    steps: dict[str, dict[str, Any]] = field(default_factory=dict)
    prompt: dict[str, Any] | None = None

    def apply(self, event: dict[str, Any]) -> None:
        """Fold one published event into the snapshot."""
        kind = event["type"]
        if kind == "run_started":
            self.steps = {s["id"]: s for s in event["steps"]}
            self.run.update(procedure=event["procedure"], state="running")
        elif kind == "step" and event["id"] in self.steps:
            self.steps[event["id"]]["state"] = event["state"]
        elif kind == "prompt":
            self.prompt = event
        elif kind == "prompt_answered":
            self.prompt = None
        elif kind == "table_live_off":
            self.run["table_status"] = event["reason"]
        elif kind in ("stopped", "finished", "analysing", "run_dir"):
            if kind == "stopped" and "exit_code" not in event:
                return  # the engine's notice; the controller's final one follows
            self.run.update({k: v for k, v in event.items() if k != "type"}, state=kind)
            if kind != "analysing":
                self.prompt = None

    def as_json(self) -> dict[str, Any]:
        """The snapshot message sent on connect."""
        return {"type": "snapshot", "run": self.run, "steps": list(self.steps.values()),
                "prompt": self.prompt}


@dataclass
class RunController:
    """Starts at most one run; routes the controlling browser's commands to it."""

    procedures: Procedures
    history: History
    rig_file: Path | None
    publish: Publish
    #: records store the runs are registered in, as by ``aatest run --records`` (None: the
    #: default store, ``AATEST_RECORDS`` or the user's file)
    records_url: str | None = None
    #: the station's signing key (``--sign-key``/``AATEST_SIGNING_KEY``; passphrase from
    #: ``AATEST_SIGNING_PASSPHRASE``), None for unsigned reports
    sign_key: Path | None = None
    #: where each finished run is also uploaded, as ``ARCHIVE/<run name>`` (``--archive``)
    archive: RemotePath | None = None
    snapshot: Snapshot = field(default_factory=Snapshot)
    _thread: threading.Thread | None = None
    _abort: AbortFlag = field(default_factory=AbortFlag)
    _responder: StationResponder | None = None

    def emit(self, event: dict[str, Any]) -> None:
        """Record the event in the snapshot and send it to every browser."""
        self.snapshot.apply(event)
        self.publish(event)

    @property
    def busy(self) -> bool:
        """Whether a run is in progress."""
        return self._thread is not None and self._thread.is_alive()

    def start(self, procedure_id: str, operator: str, unit: UnitName | None = None,
              pdf: bool = False) -> str:
        """Start a fresh run of a listed procedure for ``unit`` (else the procedure's sensor);
        ``pdf`` also prints the report to PDF. Returns the run's directory name."""
        from aatest.engine.procedure.loader import load_procedure

        path = self.procedures.path(procedure_id)
        # the run's name only: the preflight of _launch prepares the plan (and the rig) once
        run_dir = default_run_dir(load_procedure(path).procedure, self.history.runs_dir)
        self._launch(path, run_dir, resume=False, operator=operator,
                     options=_Options(unit or UnitName(), pdf))
        return run_dir.name

    def resume(self, run_name: str, operator: str) -> str:
        """Continue a stopped run from the history (its procedure must still be listed)."""
        from aatest.engine.run.run_state import RunState

        run_dir = self.history.run_dir(run_name)
        procedure_id = self.procedures.by_sha256(RunState.load(run_dir).procedure_sha256)
        if procedure_id is None:
            raise InputError(f"run {run_name}: its procedure file is no longer listed unchanged")
        meta = _recorded_unit(run_dir)
        self._launch(self.procedures.path(procedure_id), run_dir, resume=True, operator=operator,
                     options=_Options(meta, (run_dir / "report.pdf").is_file()))
        return run_name

    def abort(self, who: str) -> None:
        """Ask the running step loop to stop through the rig's safe stop."""
        if self.busy:
            self._abort.request(f"abort requested by {who}")

    def answer(self, step_id: str, who: str) -> bool:
        """Confirm the pending prompt of ``step_id`` as ``who``."""
        return self._responder is not None and self._responder.confirm(step_id, who)

    def _launch(self, path: Path, run_dir: Path, resume: bool, operator: str,
                options: _Options) -> None:
        if self.busy:
            raise InputError("a run is in progress; wait for it or abort it first")
        prepared = self._checked(path, run_dir, options.unit)
        used = self._references()
        plan = prepared.plan
        sheet, _version = sensor_datasheet(plan.sensor)
        sensors = [{"channel": s.channel, "axis": s.axis} for s in
                   sheet.sensor_infos(plan.sensor.serial)]
        self._abort = AbortFlag()
        self._responder = StationResponder(self.emit, self._abort, sensors)
        events = RunEvents(StationObserver(self.emit, self._abort),
                           self._responder, self._abort)
        self.snapshot = Snapshot(run={"name": run_dir.name, "operator": operator})
        self.emit({"type": "run_dir", "name": run_dir.name, "resume": resume,
                   "serial": plan.sensor.serial, "model": plan.sensor.model})
        self._thread = threading.Thread(
            target=self._work, args=(path, run_dir, resume, operator, events, options,
                                     prepared, used),
            daemon=True)
        self._thread.start()

    def _checked(self, path: Path, run_dir: Path, unit: UnitName) -> Any:
        """The procedure prepared after the preflight of ``aatest run`` (docs/interfaces.md
        "Preflight": plugins and their options, plan, sensor channels, logger range, disk
        space, signing key, records store); a failed check refuses the start with every
        problem at once, before the rig is built."""
        from aatest.preflight import Site, preflight

        checked = preflight(path, self.rig_file,
                            Site(None, self.sign_key, self.records_url, run_dir, True, unit))
        checked.raise_if_failed()
        return checked.prepared

    def _references(self) -> dict[str, Any]:
        """The rig's reference standards checked as ``aatest run`` checks them (an unknown,
        retired or overdue one refuses the start; a browser cannot override an overdue one),
        as the results metadata the certificate prints; empty when the rig names none."""
        from datetime import UTC, datetime

        from aatest.engine.procedure.loader import load_rig
        from aatest.records import references
        from aatest.records.store import RecordStore

        names = load_rig(self.rig_file).references if self.rig_file is not None else ()
        if not names:
            return {}
        with RecordStore.open(self.records_url) as store:
            return references.check(store, names, datetime.now(UTC).date(), None).metadata()

    def _work(self, path: Path, run_dir: Path, resume: bool, operator: str,
              events: RunEvents, options: _Options, prepared: Any,
              used: dict[str, Any]) -> None:
        from aatest.engine.run import session
        from aatest.records.errors import RecordsUnavailable
        from aatest.records.hook import registering
        from aatest.records.lab import load_lab
        from aatest.storage import publishing

        notice = None
        try:
            try:
                # registered like `aatest run`: a certificate number, then the signed bundle
                with registering(self.records_url, load_lab(), "run") as registrar, publishing(
                        run_dir, self.archive / run_dir.name if self.archive else None):
                    registrar.preflight = used  # the references the certificate names
                    session.run(path, self.rig_file, run_dir, resume, 0, self.sign_key,
                                show_progress=False, operator=operator, events=events,
                                unit=options.unit, pdf=options.pdf, prepared=prepared)
            except RecordsUnavailable as exc:
                if not (run_dir / "results.json").is_file():
                    raise
                notice = str(exc)  # the run is complete on disk; only its record is missing
        except AatestError as exc:
            self.emit({"type": "stopped", "reason": str(exc), "exit_code": exc.exit_code,
                       "resumable": (run_dir / "run_state.json").is_file()})
            return
        except Exception as exc:  # noqa: BLE001 - a worker thread must report, not vanish
            self.emit({"type": "stopped", "reason": f"internal error: {exc}", "exit_code": 4,
                       "resumable": (run_dir / "run_state.json").is_file()})
            return
        self.emit({"type": "finished", "name": run_dir.name, "notice": notice,
                   "files": present_files(run_dir), **results_summary(run_dir)})


@dataclass(frozen=True)
class _Options:
    """What a run was started with besides its procedure: the unit and the PDF."""

    unit: UnitName
    pdf: bool


def _recorded_unit(run_dir: Path) -> UnitName:
    """The unit a stopped run was recording (a resumed run goes on for the same unit)."""
    from aatest.recording.writer import STEPS_DIR, load_run_metadata

    try:
        sensor = load_run_metadata(run_dir / STEPS_DIR).get("sensor") or {}
    except (AatestError, OSError, ValueError):
        return UnitName()
    return UnitName(sensor.get("serial"), sensor.get("model"))
