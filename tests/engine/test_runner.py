"""The step loop: every step once, faults end safe, resume continues where it stopped."""

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from aatest.engine.errors import RigFault
from aatest.engine.interfaces import RigContext, SensorDatasheet
from aatest.engine.logs import SampledLog
from aatest.engine.run.rig import Rig
from aatest.engine.run.run_state import open_state
from aatest.engine.run.runner import run_plan
from aatest.engine.steps import Plan, PlannedStep, SensorRef


class _Log:
    """Every call any fake plugin receives, in order."""

    def __init__(self) -> None:
        self.calls: list[str] = []


class _Table:
    def __init__(self, log: _Log, fail_on: str | None = None) -> None:
        self.log, self.fail_on = log, fail_on

    def start(self) -> None:
        self.log.calls.append("table.start")

    def move_to(self, inner_deg: float, outer_deg: float) -> None:
        self.log.calls.append(f"move {inner_deg:g},{outer_deg:g}")

    def begin_motion(self, step: PlannedStep) -> None:
        if step.id == self.fail_on:
            raise RigFault("controller stopped answering")
        self.log.calls.append(f"begin {step.id}")

    def record(self, step: PlannedStep) -> SampledLog:
        return SampledLog("table", 2000.0, np.arange(4) / 2000.0, {"x": np.zeros(4)})

    def end_motion(self) -> None:
        self.log.calls.append("end")

    def safe_stop(self) -> None:
        self.log.calls.append("table.safe_stop")

    def close(self) -> None:
        self.log.calls.append("table.close")


class _Daq:
    def __init__(self, log: _Log) -> None:
        self.log = log

    def start(self) -> None:
        self.log.calls.append("daq.start")

    def start_logging(self, step: PlannedStep) -> None:
        self.log.calls.append(f"daq.log {step.id}")

    def stop_logging(self) -> SampledLog:
        return SampledLog("daq", 2000.0, np.arange(6) / 2000.0, {"v_sz": np.zeros(6)})

    def close(self) -> None:
        self.log.calls.append("daq.close")


class _Chamber:
    def __init__(self, log: _Log) -> None:
        self.log = log

    def set_temperature(self, setpoint_c: float) -> None:
        self.log.calls.append(f"chamber {setpoint_c:g}")

    def wait_stable(self, soak_s: float) -> float:
        self.log.calls.append(f"soak {soak_s:g}")
        return 0.0

    def off(self) -> None:
        self.log.calls.append("chamber.off")

    def close(self) -> None:
        self.log.calls.append("chamber.close")


class _Recorder:
    """Stands in for RunRecorder: remembers written step ids across 'processes'."""

    def __init__(self, written: list[str]) -> None:
        self.written = written

    def completed_step_ids(self) -> list[str]:
        return list(self.written)

    def write_step(self, step: PlannedStep, table: SampledLog, daq: SampledLog) -> None:
        self.written.append(step.id)

    #: the run metadata the runner reads and amends (the simulated parts of the rig)
    run_metadata: dict[str, object] = {}  # noqa: RUF012 - read only; amend returns a copy

    def amend_run_metadata(self, extra: dict[str, object]) -> None:
        self.run_metadata = {**self.run_metadata, **extra}


def _plan() -> Plan:
    steps = (
        PlannedStep(id="c1", kind="chamber", temperature_c=-10.0, soak_s=600.0),
        PlannedStep(id="a", kind="static", temperature_c=-10.0, duration_s=1.0, samples=4),
        PlannedStep(id="b", kind="static", temperature_c=-10.0, inner_deg=90.0, duration_s=1.0),
        PlannedStep(id="c2", kind="chamber", temperature_c=20.0, soak_s=300.0),
        PlannedStep(id="c", kind="static", temperature_c=20.0, duration_s=1.0),
    )
    return Plan(procedure="t", sensor=SensorRef(model="m", serial="T1"), steps=steps)


def _rig(log: _Log, fail_on: str | None = None) -> Rig:
    sheet = SensorDatasheet(model="m")
    context = RigContext(sensor=SensorRef(model="m"), datasheet=sheet)
    return Rig(_Table(log, fail_on), _Daq(log), _Chamber(log), sheet, context)  # type: ignore[arg-type]


def _run(
    tmp_path: Path, written: list[str], log: _Log, resume: bool, fail_on: str | None = None
) -> Any:
    state = open_state(tmp_path, "t", "abc", 1, resume)
    rig = _rig(log, fail_on)
    return run_plan(_plan(), rig, _Recorder(written), state, tmp_path, show_progress=False)


def test_every_step_runs_once_in_order_and_the_rig_ends_safe(tmp_path: Path) -> None:
    log, written = _Log(), []
    _run(tmp_path, written, log, resume=False)
    assert written == ["a", "b", "c"]
    calls = log.calls
    assert calls.index("chamber -10") < calls.index("begin a") < calls.index("chamber 20")
    assert calls.count("chamber -10") == 1 and "soak 600" in calls and "soak 300" in calls
    assert calls[-5:] == [
        "table.safe_stop", "chamber.off", "table.close", "daq.close", "chamber.close"
    ]


def test_fault_ends_in_safe_state_and_resume_repeats_nothing(tmp_path: Path) -> None:
    log, written = _Log(), []
    with pytest.raises(RigFault, match="stopped answering"):
        _run(tmp_path, written, log, resume=False, fail_on="c")
    assert written == ["a", "b"]
    assert "table.safe_stop" in log.calls and log.calls[-1] == "chamber.close"

    resumed = _Log()
    _run(tmp_path, written, resumed, resume=True)
    assert written == ["a", "b", "c"]
    assert "begin a" not in resumed.calls and "begin b" not in resumed.calls
    # the 20 °C chamber step had finished, but a resumed rig re-soaks before recording 'c'
    assert resumed.calls.index("chamber 20") < resumed.calls.index("begin c")


def test_resume_after_an_interrupted_soak_soaks_again(tmp_path: Path) -> None:
    log, written = _Log(), []
    with pytest.raises(RigFault):
        _run(tmp_path, written, log, resume=False, fail_on="a")
    resumed = _Log()
    _run(tmp_path, written, resumed, resume=True)
    assert written == ["a", "b", "c"]
    assert resumed.calls.count("chamber -10") == 1 and "soak 600" in resumed.calls


def test_a_second_fresh_run_in_the_same_directory_is_refused(tmp_path: Path) -> None:
    _run(tmp_path, [], _Log(), resume=False)
    with pytest.raises(ValueError, match="--resume"):
        _run(tmp_path, [], _Log(), resume=False)


class _SlowRecorder(_Recorder):
    """Writes a step only once the rig has begun the next one (or the run ends): a write
    made in the loop itself would wait forever (here: fail after 10 s)."""

    def __init__(self, written: list[str], log: _Log, fail_id: str | None = None) -> None:
        super().__init__(written)
        self.log, self.fail_id = log, fail_id

    def write_step(self, step: PlannedStep, table: SampledLog, daq: SampledLog) -> None:
        import time

        from aatest.engine.errors import StorageFault

        deadline = time.monotonic() + 10.0
        following = {"a": "begin b", "b": "chamber 20"}.get(step.id)
        while following and following not in self.log.calls and time.monotonic() < deadline:
            time.sleep(0.001)
        if step.id == self.fail_id:
            raise StorageFault(f"{step.id}: no space left on device")
        assert following is None or following in self.log.calls, "the write held the loop"
        super().write_step(step, table, daq)


def _run_slow(tmp_path: Path, recorder: _SlowRecorder, log: _Log, fail_on: str | None = None
              ) -> Any:
    state = open_state(tmp_path, "t", "abc", 1, False)
    return run_plan(_plan(), _rig(log, fail_on), recorder, state, tmp_path, show_progress=False)


def test_a_step_is_written_while_the_next_one_records(tmp_path: Path) -> None:
    log, written = _Log(), []
    _run_slow(tmp_path, _SlowRecorder(written, log), log)
    assert written == ["a", "b", "c"]
    assert log.calls[-5:] == [
        "table.safe_stop", "chamber.off", "table.close", "daq.close", "chamber.close"
    ]


def test_a_failed_write_stops_the_run_before_any_later_step_is_written(tmp_path: Path) -> None:
    from aatest.engine.errors import StorageFault

    log, written = _Log(), []
    with pytest.raises(StorageFault, match="b: no space"):
        _run_slow(tmp_path, _SlowRecorder(written, log, fail_id="b"), log)
    assert written == ["a"] and "table.safe_stop" in log.calls


def test_a_rig_fault_is_not_hidden_by_the_write_in_flight(tmp_path: Path) -> None:
    log, written = _Log(), []
    with pytest.raises(RigFault, match="stopped answering"):
        _run_slow(tmp_path, _SlowRecorder(written, log, fail_id="b"), log, fail_on="c")
    assert written == ["a"]
