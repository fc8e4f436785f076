"""The step loop: drive the rig through a plan, record each step atomically, resume in place.

Per recorded step: (re)establish the chamber set-point if needed, move to the start position,
start the motion and let it settle, start the DAQ (its trigger starts the table log), record,
stop the DAQ, bring the table to rest, then write the step's recording file atomically. A
fault at any point leaves the rig safe (see :mod:`aatest.engine.run.rig`) and keeps every step
completed so far; ``--resume`` continues with the first step not on disk.
"""

from __future__ import annotations

import hashlib
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import aatest
from aatest.engine.run.progress import StepProgress
from aatest.engine.run.rig import Rig, running
from aatest.engine.run.run_state import RunState
from aatest.engine.steps import Plan, PlannedStep

DEFAULT_SOAK_S = 900.0

PromptHandler = Callable[[PlannedStep], None]


def procedure_sha256(text: str) -> str:
    """Return the hex SHA-256 of the procedure text, which ties a run to its procedure."""
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def default_run_dir(procedure: str, root: Path = Path("runs")) -> Path:
    """Return ``root/<UTC time stamp>-<procedure>``, a fresh run directory name."""
    stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ")
    return root / f"{stamp}-{procedure}"


def console_prompt(step: PlannedStep) -> None:
    """Show an operator instruction; wait for Enter only when a person can answer."""
    print(f"\n>>> OPERATOR ({step.id}): {step.prompt}", file=sys.stderr)
    if sys.stdin is not None and sys.stdin.isatty():
        input("    press Enter when done ")


@dataclass
class _ChamberTracker:
    """Knows the set-point in force so a resumed run re-soaks before its next record."""

    setpoint_c: float | None = None
    soak_s: float = DEFAULT_SOAK_S

    def ensure(self, rig: Rig, step: PlannedStep) -> None:
        target = step.temperature_c
        if step.kind == "chamber":
            self.soak_s = step.soak_s if step.soak_s is not None else DEFAULT_SOAK_S
        if target is None or target == self.setpoint_c:
            return
        rig.chamber.set_temperature(target)
        rig.chamber.wait_stable(self.soak_s)
        # docs/method.md §4.2: switch the chamber off before recording (its fans and compressor
        # vibrate the table); the sensor then drifts slowly with its own thermal lag
        rig.chamber.off()
        self.setpoint_c = target


def run_metadata(
    plan: Plan, rig: Rig, procedure_text: str, seed: int, operator: str
) -> dict[str, Any]:
    """Everything that makes a recording traceable, stored in the recording itself."""
    return {
        "operator": operator,
        "table_serial": str(getattr(rig.turntable, "serial", None) or "not reported by the plugin"),
        "procedure": plan.procedure,
        "standard": plan.standard,
        "procedure_text": procedure_text,
        "procedure_sha256": procedure_sha256(procedure_text),
        "rig": rig.config,
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


def run_plan(
    plan: Plan,
    rig: Rig,
    recorder: Any,
    state: RunState,
    run_dir: Path,
    prompt: PromptHandler = console_prompt,
    show_progress: bool = True,
) -> None:
    """Execute every step not yet recorded; persist progress after each one."""
    done = set(recorder.completed_step_ids()) | set(state.chamber_steps_done)
    chamber = _ChamberTracker()
    started = time.perf_counter()
    try:
        with running(rig), StepProgress(plan, done, enabled=show_progress) as progress:
            for step in plan.steps:
                if step.id in done:
                    chamber.soak_s = step.soak_s or chamber.soak_s
                    continue
                progress.begin(step)
                if step.prompt and step.id not in state.prompts_shown:
                    prompt(step)
                    state.prompts_shown.append(step.id)
                chamber.ensure(rig, step)
                if step.kind == "chamber":
                    state.chamber_steps_done.append(step.id)
                else:
                    table, daq = execute_step(rig, step)
                    recorder.write_step(step, table, daq)
                state.save(run_dir)
                progress.end(step)
    finally:
        state.wall_duration_s += time.perf_counter() - started
        state.save(run_dir)
