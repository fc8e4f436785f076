"""The run's event seams: prompts need a person (or --confirm-prompts auto), abort is resumable."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from aatest.engine.errors import RunAborted
from aatest.engine.logs import SampledLog
from aatest.engine.run import session
from aatest.engine.run.events import AbortFlag, NullObserver, RunEvents
from aatest.engine.steps import PlannedStep

DATA = Path(__file__).parents[1] / "station" / "data"
PROMPTED = DATA / "quick-pivoted-misalignment.yaml"
SINES = DATA / "quick-sine-3-steps.yaml"


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "aatest.cli", "run", *args, "--no-progress"],
                          capture_output=True, text=True, stdin=subprocess.DEVNULL, timeout=300,
                          check=False)


def test_prompts_without_a_terminal_are_refused_before_anything_moves(tmp_path: Path) -> None:
    done = _run(str(PROMPTED), "--out", str(tmp_path / "run"))
    assert done.returncode == 2
    assert "2 operator prompt(s)" in done.stderr and "--confirm-prompts auto" in done.stderr
    assert not (tmp_path / "run").exists()


def test_confirm_prompts_auto_is_recorded(tmp_path: Path) -> None:
    run = tmp_path / "run"
    done = _run(str(PROMPTED), "--out", str(run), "--confirm-prompts", "auto")
    assert done.returncode in (0, 2), done.stderr  # 2 only for analysis errors, not prompts
    answers = json.loads((run / "run_state.json").read_text())["prompt_answers"]
    assert [a["step_id"] for a in answers] == ["s001-mis-A-e1-inner-r1", "s002-mis-B-e4-inner-r1"]
    assert {a["via"] for a in answers} == {"auto"}
    metadata = json.loads((run / "results.json").read_text())["metadata"]
    assert metadata["prompt_answers"] == answers


@dataclass
class _AbortAt(NullObserver):
    """Requests an abort while the given step is being recorded."""

    step_id: str
    abort: AbortFlag
    finished: list[str] = field(default_factory=list)
    stopped: list[str] = field(default_factory=list)

    def step_samples(self, step: PlannedStep, table: SampledLog, daq: SampledLog) -> None:
        if step.id == self.step_id:
            self.abort.request("the test")

    def step_finished(self, step: PlannedStep) -> None:
        self.finished.append(step.id)

    def run_stopped(self, reason: str) -> None:
        self.stopped.append(reason)


def test_abort_mid_step_keeps_completed_steps_and_resumes(tmp_path: Path) -> None:
    run = tmp_path / "run"
    abort = AbortFlag()
    observer = _AbortAt("s002-sine-inner-1.9531Hz-100dps2", abort)
    with pytest.raises(RunAborted) as raised:
        session.run(SINES, None, run, False, 1, None, show_progress=False,
                    events=RunEvents(observer, None, abort))
    assert raised.value.exit_code == 3
    assert observer.finished == ["s001-sine-inner-0.9766Hz-100dps2"]
    assert observer.stopped and "the test" in observer.stopped[0]
    state = json.loads((run / "run_state.json").read_text())
    assert not state["finished"]
    _, results = session.run(SINES, None, run, True, 1, None, show_progress=False)
    assert [s.id for s in results.steps] == [
        "s001-sine-inner-0.9766Hz-100dps2", "s002-sine-inner-1.9531Hz-100dps2",
        "s003-sine-inner-3.9062Hz-100dps2"]
