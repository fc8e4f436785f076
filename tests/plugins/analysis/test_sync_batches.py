"""How the sync pass shares out its work: the sine steps of one frequency go to a worker
together, and each step decodes only the channels its watches read.

Why batches: a watched FRF point's segment fit needs a pseudo-inverse that depends only on
the frequency and record length; a worker computes it once and keeps it, so steps of one
frequency in one worker compute it once, not once per worker
(:func:`aatest.plugins.analysis.synced_steps.relations`).
"""

from __future__ import annotations

from typing import Any

from aatest.engine.steps import PlannedStep
from aatest.plugins.analysis.synced_steps import _batches
from aatest.recording.dataset import LazySteps


def _steps(planned: list[PlannedStep]) -> LazySteps:
    def load(index: int, source: str, channels: Any) -> Any:
        raise AssertionError("batching decodes nothing")

    return LazySteps(planned, load, [{} for _ in planned])


def _sine(step_id: str, frequency_hz: float, group: str) -> PlannedStep:
    return PlannedStep(id=step_id, kind="sine", axis="inner", frequency_hz=frequency_hz,
                       group=group)


def test_sine_steps_of_one_frequency_share_a_batch_and_other_steps_stand_alone() -> None:
    planned = [_sine("a1", 1.0, "a"), _sine("a2", 2.0, "a"),
               PlannedStep(id="s1", kind="static"), PlannedStep(id="s2", kind="static"),
               _sine("b1", 1.0, "b"), _sine("b2", 2.0, "b"), _sine("b3", 3.0, "b"),
               _sine("c2", 2.0, "c")]
    steps = _steps(planned)
    # the largest batch first (the workers then finish together), else by first step
    assert _batches(steps, range(len(planned))) == [[1, 5, 7], [0, 4], [2], [3], [6]]
    # a subset and any order: each batch keeps the order given
    assert _batches(steps, [7, 6, 1, 0, 2]) == [[7, 1], [6], [0], [2]]


def test_every_index_is_in_exactly_one_batch() -> None:
    planned = [_sine(f"s{i}", float(1 + i % 5), f"g{i // 5}") for i in range(23)]
    indices = list(range(23))[::-1]
    batches = _batches(_steps(planned), indices)
    assert sorted(i for batch in batches for i in batch) == sorted(indices)
    assert all(len({planned[i].frequency_hz for i in batch}) == 1 for batch in batches)


def test_the_phase_trend_asks_only_the_moving_axis_motion_of_a_step() -> None:
    """What the trend reads of a sine step (its moving axis' position and acceleration) is
    all the sync pass decodes for it: the other axis' delta-coded encoder is left alone."""
    from pathlib import Path

    from aatest.engine.datasheet import SensorInfo
    from aatest.plugins.analysis.sync_trend import watch_trends
    from aatest.plugins.analysis.sync_watches import _REGISTERED
    from aatest.recording.dataset import Dataset

    inner = _sine("i", 1.0, "a")
    outer = PlannedStep(id="o", kind="sine", axis="outer", frequency_hz=1.0, group="a")
    steps = _steps([inner, outer])
    data = Dataset(procedure="p", sample_rate_hz=2000.0, sensors=(SensorInfo(channel="v_z"),),
                   steps=steps, source=Path("."))
    watch_trends(data)
    watches = _REGISTERED[steps]
    assert watches.channels(inner)["table"] == [
        "sync_pulse", "fp_latch_s", "inner_position_deg", "inner_accel_dps2"]
    assert watches.channels(outer)["table"] == [
        "sync_pulse", "fp_latch_s", "outer_position_deg", "outer_accel_dps2"]
    assert watches.channels(outer)["daq"] == ["sync_pulse", "trigger", "v_z"]
