"""The drift from the sine steps' phase trend where the edges without latch times only bound it.

Twin records without ``fp_latch_s`` whose edges cross no table sample (|drift| × record below
one sample): the edges bound the drift to tens of ppm, the sensor's phase against the table's
encoder fixes it. The truth is the twin's crystal; the tolerances are derived beside each
assertion from the stated uncertainty.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from test_unlatched import _without_latch

from aatest.clocksync.freeze_pulse import clock_relation, synchronise
from aatest.clocksync.phase_trend import (
    PhaseTrend,
    combined_drift,
    step_phase_trend,
    trend_slope_range,
)
from aatest.engine.interfaces import AnalysisContext
from aatest.engine.logs import SampledLog
from aatest.engine.steps import PlannedStep
from aatest.parallel.forked import WORKERS_ENV
from aatest.plugins.analysis.sync import SyncAnalysis, SyncedWatch, watch_synced
from aatest.recording.dataset import Dataset, LazySteps, _subset
from aatest.twin import model as m
from aatest.twin.api import simulate_dataset

FS_HZ = 2000.0
SAMPLES = 16384
#: sensor noise: at 200 °/s² (0.2 V) it leaves ≈ 0.15 ppm of trend at 8 Hz over the 6 s read
#: (σ/A·√(24/N)/(2π·f·T)); at 1 mV it is ≈ 0.7 ppm (the realistic sensor's case: see the sweep)
NOISE_V = 2e-4


def _step(sid: str, kind: str, cycles: int) -> PlannedStep:
    f = cycles * FS_HZ / SAMPLES if kind == "sine" else None
    return PlannedStep(id=sid, kind=kind, axis="inner", samples=SAMPLES, sample_rate_hz=FS_HZ,
                       duration_s=SAMPLES / FS_HZ, frequency_hz=f,
                       accel_dps2=200.0 if kind == "sine" else None)


def _dataset(drift_ppm: float, seed: int, steps: list[PlannedStep], latch: bool) -> Dataset:
    daq = m.DaqModel(clock_drift=m.ClockDrift(drift_ppm=drift_ppm), sync_edge_jitter_s=3e-6)
    rig = m.RigModel(sensors=[m.SensorModel(channel="v_sz", axis="I", noise_rms_v=NOISE_V)],
                     daq=daq)
    data = simulate_dataset(rig, steps, seed)
    if latch:
        return data
    return replace(data, steps=tuple(_without_latch(s) for s in data.steps))


def _sync(data: Dataset) -> dict[str, object]:
    out = SyncAnalysis().run(data, AnalysisContext())
    return out.result.model_dump()


@pytest.mark.parametrize("drift_ppm", [26.3, -4.7])
def test_an_8_hz_step_fixes_the_drift_its_edges_only_bound(drift_ppm: float) -> None:
    """8.2 s at 7.8 Hz, 0.2 mV sensor noise: the edges leave tens of ppm, the trend a few tenths;
    the truth lies within 3 u of the trend (u from the segments' scatter: a 0.3 % chance
    outside for a normal error)."""
    raw = _without_latch(_dataset(drift_ppm, 5, [_step("s", "sine", 64)], True).steps[0])
    edges = clock_relation(raw)
    assert edges.drift_u_ppm > 5.0  # no crossing: only bounded
    trend = step_phase_trend(synchronise(raw, edges))
    assert trend is not None and trend.channel == "v_sz"
    assert trend.u_ppm < 0.5
    assert abs(trend.drift_ppm - drift_ppm) <= 3.0 * trend.u_ppm


def test_static_and_short_steps_show_no_trend() -> None:
    """A static step and a sine of fewer than four cycles after settling carry no trend."""
    data = _dataset(10.0, 3, [_step("a", "static", 0), _step("b", "sine", 4)], False)
    for raw in data.steps:
        assert step_phase_trend(synchronise(raw, clock_relation(raw))) is None


def test_trend_range_inside_the_edges() -> None:
    """The trend's interval is clipped to the edges' range; disjoint ranges leave the edges."""
    edges = (1.0 + 10e-6, 1.0 + 40e-6)
    lo, hi = trend_slope_range((12.0, 1.0), edges) or (0.0, 0.0)
    assert lo == pytest.approx(edges[0]) and hi == pytest.approx(1.0 + (12.0 + np.sqrt(3)) * 1e-6)
    assert trend_slope_range((80.0, 1.0), edges) is None
    # two steps disagreeing beyond their u: the pooled u grows with the scatter (Birge ratio)
    pooled = combined_drift([PhaseTrend("a", 0.0, 0.1, "v", 8.0, 16),
                             PhaseTrend("b", 1.0, 0.1, "v", 8.0, 16)])
    assert pooled is not None and pooled[0] == pytest.approx(0.5) and pooled[1] > 0.4


def test_the_sync_analysis_refits_every_step_with_the_pooled_trend() -> None:
    """Without latch times the sync analysis narrows every step (the static one too: one
    crystal) to the pooled trend and says so; with latch times nothing changes."""
    drift = 17.0
    plan = [_step("s1", "sine", 64), _step("st", "static", 0), _step("s2", "sine", 32)]
    blind = _sync(_dataset(drift, 8, plan, False))
    steps = blind["steps"]
    assert isinstance(steps, list)
    assert all(s["drift_source"] == "edges + sine phase trend" for s in steps)
    u = float(blind["drift_u_ppm"])  # type: ignore[arg-type]
    assert u < 0.5 and abs(float(blind["drift_ppm"]) - drift) <= 3.0 * u  # type: ignore[arg-type]
    latched = _sync(_dataset(drift, 8, plan, True))
    assert all(s["drift_source"] == "latch times" for s in latched["steps"])  # type: ignore[union-attr]
    # latched: drift to the 3 µs edge jitter over 8 s (≈0.05 ppm); 0.3 ppm is 6σ
    assert abs(float(latched["drift_ppm"]) - drift) < 0.3  # type: ignore[arg-type]


def test_a_static_run_stays_bounded_by_its_edges() -> None:
    """No sine step: the drift is what the edges allow, stated as such (the limit)."""
    data = _dataset(3.0, 4, [_step("st", "static", 0)], False)
    result = _sync(data)
    step = result["steps"][0]  # type: ignore[index]
    assert step["drift_source"] == "edges"
    lo_hi = clock_relation(data.steps[0]).slope_range
    assert lo_hi is not None and (lo_hi[0] - 1) * 1e6 <= 3.0 <= (lo_hi[1] - 1) * 1e6


def _lazy(data: Dataset, volts_read: list[int] | None = None) -> Dataset:
    """The same steps as a recording's: decoded (a channel subset) when read; each decode of
    the sensor's volts (in this process) counted in ``volts_read``."""
    steps = list(data.steps)

    def load(index: int, source: str, channels: object) -> SampledLog:
        if volts_read is not None and source == "daq" and (
                channels is None or "v_sz" in channels):  # type: ignore[operator]
            volts_read.append(index)
        log = steps[index].table if source == "table" else steps[index].daq
        return log if channels is None else _subset(log, channels)  # type: ignore[arg-type]

    counts = [{"table": s.samples("table"), "daq": s.samples("daq")} for s in steps]
    return replace(data, steps=LazySteps([s.step for s in steps], load, counts))


def test_a_recordings_steps_take_the_trend_as_steps_in_memory_do(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Lazy steps (a recording: decoded per read, relations fitted apart) end with the same
    refitted relations, and the analyses read the steps synchronised with them."""
    plan = [_step("s1", "sine", 64), _step("s2", "sine", 32)]
    memory = _dataset(9.0, 6, plan, False)
    monkeypatch.setenv(WORKERS_ENV, "1")  # the sync pass in this process: its reads counted
    volts_read: list[int] = []
    lazy = _lazy(memory, volts_read)
    # an analysis watching the volts in the sync pass, as the FRF does
    watch_synced(lazy, "volts", SyncedWatch({"daq": ["v_sz"]}, lambda _: True, lambda _: None))
    out = SyncAnalysis().run(lazy, AnalysisContext())
    # the trends come from the sync pass's own decode: the volts are read once per step
    assert sorted(volts_read) == [0, 1]
    kept = _sync(memory)
    assert out.result.drift_ppm == pytest.approx(float(kept["drift_ppm"]), abs=1e-9)
    assert all(s.drift_source == "edges + sine phase trend" for s in out.result.steps)
    synced = list(out.steps)
    assert all(s.relation.phase_trend for s in synced)
    assert synced[0].relation.drift_ppm == pytest.approx(out.result.drift_ppm, abs=1e-9)
