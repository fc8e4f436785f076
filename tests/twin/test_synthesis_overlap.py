"""The twin computes a step's table log on a second thread while the DAQ log computes, the
table log's uniforms drawn ahead from the stream both share; the logs must be exactly those of
computing one after the other.

Exact comparison: both paths run the same float64 operations on the same draws of the same
seeded streams; only which thread computes differs. Any difference would mean a draw moved
from one log to the other, or a thread touched a shared state.
"""

from __future__ import annotations

import numpy as np
import pytest
from twin_steps import rate_step, sine_step, static_step

from aatest.engine.logs import SampledLog
from aatest.engine.steps import PlannedStep
from aatest.twin import step_synthesis, table_log
from aatest.twin.defaults import realistic_rig_model
from aatest.twin.step_setup import LazyTruth, StepSetup
from aatest.twin.step_synthesis import synthesise
from aatest.twin.synthesis import _daq_log
from aatest.twin.table_log import table_log_with_truth
from aatest.twin.world import World


def _setup(step: PlannedStep) -> StepSetup:
    world = World(realistic_rig_model(), seed=11)
    world.motor_on = True
    world.move_to(0.0, 0.0)
    world.begin_motion(step)
    world.start_daq()
    return world._setup()


def _same(a: SampledLog, b: SampledLog) -> None:
    assert np.array_equal(a.time_s, b.time_s)
    assert a.channels.keys() == b.channels.keys()
    for name, values in a.channels.items():
        assert np.array_equal(values, b.channels[name]), name


STEPS = [sine_step(7.0, 400.0, samples=4096), sine_step(0.7, 50.0, samples=4096, axis="outer"),
         static_step(samples=4096), rate_step(20.0, samples=4096)]


def _serial(setup: StepSetup) -> tuple[SampledLog, dict, SampledLog, LazyTruth]:
    rng = np.random.default_rng(5)
    table, table_truth = table_log_with_truth(setup, rng)  # first the table log, then the DAQ log
    return table, table_truth, *_daq_log(setup, rng, np.random.default_rng(6))


def _counted_table_logs(monkeypatch: pytest.MonkeyPatch) -> list[object]:
    """Record the generator each table log is computed from."""
    calls: list[object] = []
    real = table_log.table_log_with_truth

    def counted(setup: StepSetup, rng: np.random.Generator, *args: object) -> object:
        calls.append(rng)
        return real(setup, rng, *args)  # type: ignore[arg-type]

    monkeypatch.setattr(step_synthesis, "table_log_with_truth", counted)
    return calls


@pytest.mark.parametrize("step", STEPS, ids=lambda s: s.id)
def test_overlapped_synthesis_equals_the_sequential_one(
        step: PlannedStep, monkeypatch: pytest.MonkeyPatch) -> None:
    setup = _setup(step)
    table, table_truth, daq, truth = _serial(setup)
    calls = _counted_table_logs(monkeypatch)
    overlapped = synthesise(setup, np.random.default_rng(5),
                            drift_rng=np.random.default_rng(6))
    # drawn ahead and concurrent: one table log, from the tape (no serial redo)
    assert len(calls) == 1 and isinstance(calls[0], step_synthesis.UniformTape)
    _same(overlapped.table, table)
    _same(overlapped.daq, daq)
    for key in ("angle_deg", "accel_dps2", "daq_time_s", "volts_v_sz", "alpha_v_sz"):
        expected = table_truth[key] if key in table_truth else truth[key]
        assert np.array_equal(overlapped.truth[key], expected), key


@pytest.mark.parametrize("count", ["table_uniforms", "floor_uniforms", "record_uniforms",
                                   "stamp_uniforms"])
@pytest.mark.parametrize("extra", [2, -2], ids=["too-many", "too-few"])
def test_a_miscounted_draw_ahead_redoes_the_step_serially(
        count: str, extra: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """If a log draws other than counted (here: a count is off by one pair), the step is
    redone from the saved stream states: slower, the same numbers."""
    setup = _setup(STEPS[0])
    table, _, daq, _ = _serial(setup)
    counted = getattr(step_synthesis, count)
    monkeypatch.setattr(step_synthesis, count, lambda *a: counted(*a) + extra)
    calls = _counted_table_logs(monkeypatch)
    redone = synthesise(setup, np.random.default_rng(5), drift_rng=np.random.default_rng(6))
    assert len(calls) == 2 and isinstance(calls[1], np.random.Generator)
    _same(redone.table, table)
    _same(redone.daq, daq)


def test_two_streams_compute_concurrently_with_their_own_draws() -> None:
    """With a DAQ stream of its own (a long record) nothing is drawn ahead: each log draws
    its own stream."""
    setup = _setup(STEPS[2])
    both = synthesise(setup, np.random.default_rng(5), np.random.default_rng(7),
                      np.random.default_rng(6))
    table, _ = table_log_with_truth(setup, np.random.default_rng(5))
    daq, _ = _daq_log(setup, np.random.default_rng(7), np.random.default_rng(6))
    _same(both.table, table)
    _same(both.daq, daq)
