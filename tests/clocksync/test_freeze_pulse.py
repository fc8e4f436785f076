"""Freeze-pulse synchronisation against synthetic logs with a known clock relation."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from synthetic_rig import SynthRig, make_dataset, make_step, sine_step

from aatest.clocksync import fit_clock_relation, synchronise, synchronise_all
from aatest.engine.analysis.passes import run_analysis
from aatest.engine.errors import AnalysisError
from aatest.engine.logs import SampledLog
from aatest.plugins.analysis.sync import SyncOutput
from aatest.recording.dataset import StepData


@pytest.mark.parametrize("drift_ppm", [-40.0, 0.0, 12.0, 250.0], ids=["neg", "zero", "pos", "big"])
def test_drift_and_offset_recovered(drift_ppm: float) -> None:
    rig = SynthRig(drift_ppm=drift_ppm)
    synced = synchronise(make_step(sine_step("s", 8, 100.0), rig, seed=3))
    rel = synced.relation
    assert abs(rel.drift_ppm - drift_ppm) < 1.0
    assert abs(rel.offset_s - (-rig.lead_s)) < 0.25e-3  # one DAQ sample of edge ambiguity
    assert rel.residual_rms_us < 10.0
    assert rel.edges_used > 70


def test_resampled_sensor_is_on_table_time() -> None:
    """Without sensor dynamics the synced sensor follows the table acceleration sample by sample."""
    from synthetic_rig import SynthSensor

    sensor = SynthSensor(natural_frequency_hz=1e6, delay_s=0.0, noise_v=0.0)
    rig = SynthRig(sensors=(sensor,), position_noise_deg=0.0, drift_ppm=80.0)
    synced = synchronise(make_step(sine_step("s", 16, 200.0), rig, seed=5))
    volts = (synced.daq["v_sz"] - sensor.bias_v) / sensor.scale_v_per_dps2
    accel = synced.table["inner_accel_dps2"]
    # alignment to ≤ 0.25 ms (half a sample): 200 °/s² at 1.95 Hz moves ≤ 0.6 °/s² in that time
    assert_allclose(volts[5:-5], accel[5:-5], atol=0.6)


def test_jitter_and_missing_latch_still_within_a_sample() -> None:
    rig = SynthRig(jitter_s=6e-6, latch=False)
    step = sine_step("s", 8, 100.0)
    rel = synchronise(make_step(step, rig, seed=4)).relation
    # without the latch time the table edges are quantised to one sample over the record
    assert abs(rel.drift_ppm - rig.drift_ppm) < 1e6 / 2000 / step.duration_s
    # the offset is pinned by the trigger, which this rig raises on the first DAQ sample after
    # the table's start: up to one DAQ sample late
    assert abs(rel.offset_s + rig.lead_s) < 1.0 / 2000
    assert not rel.latched


def _without_table_edges(data: StepData) -> StepData:
    ch = dict(data.table.channels)
    ch["sync_pulse"] = np.zeros(len(data.table))
    return replace(data, table=SampledLog("table", 2000.0, data.table.time_s, ch))


def _with_scrambled_edges(data: StepData) -> StepData:
    ch = dict(data.table.channels)
    rng = np.random.default_rng(0)
    ch["sync_pulse"] = (rng.random(len(data.table)) > 0.5).astype(float)
    return replace(data, table=SampledLog("table", 2000.0, data.table.time_s, ch))


@pytest.mark.parametrize("spoil, match", [(_without_table_edges, "missing"),
                                          (_with_scrambled_edges, "inconsistent")],
                         ids=["missing", "inconsistent"])
def test_refuses_bad_edges(spoil, match: str) -> None:  # type: ignore[no-untyped-def]
    data = spoil(make_step(sine_step("s", 8, 100.0), SynthRig(), seed=1))
    with pytest.raises(AnalysisError, match=match):
        synchronise(data)


def test_analysis_summary_carries_the_synced_steps() -> None:
    steps = [sine_step(f"s{i}", 8 + i, 100.0) for i in range(3)]
    data = make_dataset(steps, SynthRig(drift_ppm=-7.5))
    out = run_analysis("sync", data)
    v = out.result.model_dump(mode="json")
    assert set(v) >= {"drift_ppm", "offset_s", "residual_rms_us", "edges_used"}
    assert abs(v["drift_ppm"] + 7.5) < 1.0 and len(v["steps"]) == 3
    # the synchronised steps travel with the output (for dependants), not in results.json
    assert isinstance(out, SyncOutput) and [s.step.id for s in out.steps] == ["s0", "s1", "s2"]
    assert "steps" in v and all(set(row) >= {"step", "drift_ppm"} for row in v["steps"])
    again = synchronise_all(data)
    assert [s.relation for s in again] == [s.relation for s in out.steps]



@settings(max_examples=40, deadline=None)
@given(drift=st.floats(-500, 500), offset=st.floats(-2.0, 2.0), jitter_us=st.floats(0, 5),
       seed=st.integers(0, 2**31))
def test_clock_relation_property(drift: float, offset: float, jitter_us: float, seed: int) -> None:
    """Any drift within ±500 ppm and offset are recovered from latch-exact edges."""
    rng = np.random.default_rng(seed)
    t_daq = 0.0025 + np.arange(3000) * 0.01
    t_table = offset + t_daq * (1 + drift * 1e-6) + rng.normal(0, jitter_us * 1e-6, t_daq.size)
    keep = (t_table > t_table[0] + 0.3) & (t_table < t_table[-1] - 0.4)  # DAQ runs longer
    rel = fit_clock_relation("p", t_table[keep], t_daq, offset0=offset + 0.0003)
    assert abs(rel.drift_ppm - drift) < 0.05 + 3 * rel.drift_u_ppm
    assert abs(rel.offset_s - offset) < 5e-6 + 5 * jitter_us * 1e-6
    assert rel.residual_rms_us < 2 * jitter_us + 0.1
