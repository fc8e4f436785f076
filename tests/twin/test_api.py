"""simulate_step / simulate_dataset: shapes, channels, truth and reproducibility."""

from __future__ import annotations

import numpy as np
from numpy.testing import assert_allclose
from twin_steps import sine_step, static_step

from aatest.engine.logs import DAQ_AUX_CHANNELS, TABLE_CHANNELS
from aatest.plugins.sensors.sr207 import SR207Unit
from aatest.twin.api import (
    nominal_rig_model,
    realistic_rig_model,
    simulate_dataset,
    simulate_step,
)
from aatest.twin.model import RigModel

#: the three-sensor unit (S_Z on I, S_Y on O, S_X on P)
AAMU = SR207Unit().datasheet()


def test_simulate_step_logs_have_contract_channels() -> None:
    step = sine_step(1.0, 100.0)
    sim = simulate_step(RigModel(), step, seed=1)
    assert set(sim.table.channels) == set(TABLE_CHANNELS)
    assert set(DAQ_AUX_CHANNELS) | {"v_sz"} == set(sim.daq.channels)
    assert len(sim.table) == step.samples
    # the DAQ starts earlier and stops later than the table log
    assert len(sim.daq) > step.samples + 0.3 * 2000
    assert sim.truth["time_s"].shape == (step.samples,)
    assert_allclose(np.max(np.abs(sim.truth["accel_dps2"])), 100.0, rtol=2e-3)


def test_same_seed_same_logs_and_different_seed_differs() -> None:
    step = sine_step(2.0, 50.0, samples=4096)
    model = realistic_rig_model()
    a, b, c = (simulate_step(model, step, seed=s) for s in (3, 3, 4))
    assert_allclose(a.daq["v_sz"], b.daq["v_sz"], rtol=0, atol=0)
    assert not np.allclose(a.daq["v_sz"], c.daq["v_sz"])


def test_nominal_model_is_ideal() -> None:
    """Nominal replay: one clock, no noise, output = bias + K·α exactly (no dynamics)."""
    step = sine_step(1.0, 200.0, samples=4096)
    sim = simulate_step(nominal_rig_model(), step, seed=0)
    lead = round(0.35 * 2000)
    v = sim.daq["v_sz"][lead: lead + step.samples]
    expected = 2.5 + 0.004014 * sim.truth["accel_dps2"]
    assert_allclose(v, expected, atol=1e-7)
    assert sim.truth["drift_ppm"] == 0.0
    assert_allclose(sim.daq.time_s[lead] + sim.truth["offset_s"], 0.0, atol=1e-12)


def test_simulate_dataset_builds_dataset() -> None:
    steps = [static_step(samples=2048, id="a"), sine_step(1.0, 10.0, samples=2048, id="b")]
    data = simulate_dataset(realistic_rig_model(AAMU), steps, seed=5)
    assert [s.step.id for s in data.steps] == ["a", "b"]
    assert [s.channel for s in data.sensors] == ["v_sz", "v_sy", "v_sx"]
    assert data.sample_rate_hz == 2000.0
