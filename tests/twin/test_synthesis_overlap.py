"""The twin computes a step's rigid table-top motion on a second thread while the table log
draws its noise; the logs must be exactly those of computing one after the other.

Exact comparison: both paths run the same float64 operations on the same draws of the same
seeded streams; only which thread runs the motion (which draws nothing) differs. Any
difference would mean the motion touched a random stream or a shared state.
"""

from __future__ import annotations

import numpy as np
import pytest
from twin_steps import sine_step

from aatest.engine.logs import SampledLog
from aatest.engine.steps import PlannedStep
from aatest.twin.defaults import realistic_rig_model
from aatest.twin.synthesis import StepSetup, _daq_log, _table_log, synthesise
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


@pytest.mark.parametrize("step", [sine_step(7.0, 400.0, samples=4096),
                                  sine_step(0.7, 50.0, samples=4096, axis="outer")],
                         ids=lambda s: s.id)
def test_overlapped_synthesis_equals_the_sequential_one(step: PlannedStep) -> None:
    setup = _setup(step)
    overlapped = synthesise(setup, np.random.default_rng(5),
                            drift_rng=np.random.default_rng(6))
    rng = np.random.default_rng(5)
    table, table_truth = _table_log(setup, rng)  # first the table log, then the DAQ log
    daq, truth = _daq_log(setup, rng, np.random.default_rng(6))
    _same(overlapped.table, table)
    _same(overlapped.daq, daq)
    for key in ("angle_deg", "accel_dps2", "daq_time_s", "volts_v_sz", "alpha_v_sz"):
        expected = table_truth[key] if key in table_truth else truth[key]
        assert np.array_equal(overlapped.truth[key], expected), key
