"""`run` checks each step's sync as it is recorded: a step that cannot be synchronised ends
the run at once (exit 3, the step named), with the rig safe and the step kept."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from synthetic_rig import SynthRig, make_step, sine_step

from aatest.engine.errors import EXIT_RIG_FAULT, RigFault
from aatest.engine.interfaces import RigContext, SensorDatasheet
from aatest.engine.logs import SampledLog
from aatest.engine.run.rig import Rig
from aatest.engine.run.run_state import open_state
from aatest.engine.run.runner import run_plan
from aatest.engine.steps import Plan, PlannedStep, SensorRef


class _Rig:
    """Table and DAQ fakes that play synthetic steps; the table loses its pulse on ``bad``."""

    def __init__(self, calls: list[str], bad: str) -> None:
        self.calls, self.bad = calls, bad
        self._step: PlannedStep | None = None

    def start(self) -> None:
        self.calls.append("start")

    def move_to(self, inner_deg: float, outer_deg: float) -> None:
        pass

    def begin_motion(self, step: PlannedStep) -> None:
        self.calls.append(f"begin {step.id}")
        self._step = step

    def start_logging(self, step: PlannedStep) -> None:
        pass

    def record(self, step: PlannedStep) -> SampledLog:
        table = make_step(step, SynthRig(latch=False), seed=1).table
        if step.id != self.bad:
            return table
        channels = {**table.channels, "sync_pulse": np.zeros(len(table))}
        return SampledLog("table", table.sample_rate_hz, table.time_s, channels)

    def stop_logging(self) -> SampledLog:
        assert self._step is not None
        return make_step(self._step, SynthRig(latch=False), seed=1).daq

    def end_motion(self) -> None:
        pass

    def safe_stop(self) -> None:
        self.calls.append("safe_stop")

    def close(self) -> None:
        pass


class _Chamber:
    def close(self) -> None:
        pass

    def off(self) -> None:
        pass


class _Recorder:
    def __init__(self) -> None:
        self.written: list[str] = []

    def completed_step_ids(self) -> list[str]:
        return list(self.written)

    def write_step(self, step: PlannedStep, table: SampledLog, daq: SampledLog) -> None:
        self.written.append(step.id)

    #: the run metadata the runner reads and amends (the simulated parts of the rig)
    run_metadata: dict[str, object] = {}  # noqa: RUF012 - read only; amend returns a copy

    def amend_run_metadata(self, extra: dict[str, object]) -> None:
        self.run_metadata = {**self.run_metadata, **extra}


def test_a_step_that_cannot_be_synchronised_stops_the_run_there(tmp_path: Path) -> None:
    steps = tuple(sine_step(f"s{i}", 4, 100.0) for i in range(1, 4))
    plan = Plan(procedure="t", sensor=SensorRef(model="m", serial="T1"), steps=steps,
                analysis=["sync"])
    calls: list[str] = []
    fake = _Rig(calls, bad="s2")
    sheet = SensorDatasheet(model="m")
    rig = Rig(fake, fake, _Chamber(), sheet,  # type: ignore[arg-type]
              RigContext(sensor=SensorRef(model="m"), datasheet=sheet))
    recorder = _Recorder()
    with pytest.raises(RigFault, match=r"step s2: sync edges missing") as caught:
        run_plan(plan, rig, recorder, open_state(tmp_path, "t", "abc", 1, False), tmp_path,
                 show_progress=False)
    assert caught.value.exit_code == EXIT_RIG_FAULT
    assert "begin s3" not in calls and calls[-1] == "safe_stop"  # stopped at once, safe
    assert recorder.written == ["s1", "s2"]  # the bad step's data is kept
