"""The run's live status poll: readings on the table's clock, optional everywhere, harmless.

A table whose clock the test moves by hand shows the lab-time schedule (a reading of a clock
that stood still is not passed on); a table without ``status()``, a failing one and an
observer without the optional methods all leave the step alone. A run on the twin hands the
station's observer readings during every recorded step, on the twin's lab clock.
"""

from __future__ import annotations

import itertools
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from aatest.engine.errors import RigFault
from aatest.engine.interfaces import TableStatus
from aatest.engine.run.events import NullObserver, RunEvents
from aatest.engine.run.session import run
from aatest.engine.run.status_poll import NO_STATUS, StatusPoll, polling_status
from aatest.engine.steps import PlannedStep

STEP = PlannedStep(id="s001-rest", kind="static", samples=100)
SINES = Path(__file__).parents[1] / "station" / "data" / "quick-sine-3-steps.yaml"
PERIOD_S = 0.01  # fast polls: the tests wait for readings, not for wall time


@dataclass
class ManualClockTable:
    """A table whose controller clock moves only when the test says (like the twin's)."""

    time_s: float = 0.0
    reads: int = 0
    fail_after: int | None = None

    def status(self) -> TableStatus:
        self.reads += 1
        if self.fail_after is not None and self.reads > self.fail_after:
            raise RigFault("controller stopped answering")
        return TableStatus(time_s=self.time_s, clock="controller",
                           inner_position_deg=10.0 * self.time_s, inner_rate_dps=10.0)


@dataclass
class Seen(NullObserver):
    """Collects the optional status events."""

    readings: list[tuple[str, TableStatus]] = field(default_factory=list)
    unavailable: list[tuple[str, str]] = field(default_factory=list)

    def table_status(self, step: PlannedStep, status: TableStatus) -> None:
        self.readings.append((step.id, status))

    def table_status_unavailable(self, step: PlannedStep, reason: str) -> None:
        self.unavailable.append((step.id, reason))


def _until(condition: object, timeout_s: float = 10.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():  # type: ignore[operator]
        assert time.monotonic() < deadline, "condition not met in time"
        time.sleep(0.005)


def test_readings_are_passed_on_only_when_the_tables_clock_moved_on() -> None:
    table, seen = ManualClockTable(), Seen()
    with polling_status(table, STEP, seen, PERIOD_S) as poll:
        assert isinstance(poll, StatusPoll)
        _until(lambda: table.reads >= 5)
        assert len(seen.readings) == 1  # the clock stood still: one reading of it
        table.time_s = 0.005  # less than a period later: nothing new to show
        _until(lambda: table.reads >= 10)
        assert len(seen.readings) == 1
        table.time_s = 3.0  # a jump, as the twin's lab clock makes
        _until(lambda: len(seen.readings) == 2)
        table.time_s = 3.5
    # the step ended well: one last reading shows where it left the table
    assert [s.time_s for _, s in seen.readings] == [0.0, 3.0, 3.5]
    assert seen.readings[-1][1].inner_position_deg == 35.0
    assert not seen.unavailable and poll.points == 3


def test_a_table_without_status_is_named_once_and_the_step_goes_on() -> None:
    seen = Seen()
    with polling_status(object(), STEP, seen, PERIOD_S) as poll:
        assert poll is None
    assert seen.unavailable == [(STEP.id, NO_STATUS)] and not seen.readings


def test_a_failing_read_stops_polling_without_ending_the_step() -> None:
    table, seen = ManualClockTable(fail_after=2), Seen()
    with polling_status(table, STEP, seen, PERIOD_S):
        _until(lambda: bool(seen.unavailable))
        time.sleep(10 * PERIOD_S)
    assert table.reads == 3  # two readings, the failed one, then no more
    ((step_id, reason),) = seen.unavailable
    assert step_id == STEP.id and "controller stopped answering" in reason


def test_a_fault_in_the_step_stops_the_poll_without_a_last_read() -> None:
    table, seen = ManualClockTable(), Seen()
    with pytest.raises(RigFault, match="servo"), polling_status(table, STEP, seen, PERIOD_S):
        _until(lambda: table.reads >= 1)
        table.time_s = 1.0
        reads = table.reads
        raise RigFault("servo error")
    assert table.reads <= reads + 1  # at most a poll already under way, no last read
    # the step did not wait for the poll thread; it ends on its own at its next wake-up
    _until(lambda: not any(t.name.startswith("status-poll") for t in threading.enumerate()))


def test_an_observer_without_the_optional_methods_keeps_working() -> None:
    table = ManualClockTable()
    with polling_status(table, STEP, NullObserver(), PERIOD_S) as poll:
        _until(lambda: table.reads >= 3)
    assert poll is not None and poll.points == 1


def test_a_run_on_the_twin_polls_every_recorded_step_on_its_lab_clock(tmp_path: Path) -> None:
    seen = Seen()
    run(SINES, None, tmp_path / "run", False, 3, None, show_progress=False,
        events=RunEvents(seen))
    steps = sorted({step_id for step_id, _ in seen.readings})
    assert len(steps) == 3 and not seen.unavailable
    for step_id in steps:
        readings = [s for i, s in seen.readings if i == step_id]
        times = [s.time_s for s in readings]
        # on the lab clock, at least a period apart; the first before the motion, the last
        # after the table came back to rest at the step's start (0°, at rest)
        assert all(b - a >= 0.1 for a, b in itertools.pairwise(times))
        assert len(readings) >= 2 and readings[-1].clock == "controller"
        assert readings[-1].inner_position_deg == 0.0 and readings[-1].inner_rate_dps == 0.0
