"""Sync without latch times (issue 33): twin records whose table logs no ``fp_latch_s``.

The twin registers every pulse edge one controller cycle late on a table grid that starts at
the DAQ's trigger sample, so without latch times the edges' quantisation is a sawtooth, not
noise: the drift is fixed precisely only where edges cross a table sample. The tests assert
the truth against what the fit claims: drift within 0.5 ppm where the record holds such
crossings, and the truth inside the stated feasible range everywhere.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from aatest.clocksync.edges import joint_slope_range
from aatest.clocksync.freeze_pulse import clock_relation, rising_edges
from aatest.engine.logs import SampledLog
from aatest.engine.steps import PlannedStep
from aatest.plugins.analysis.sync import joint_drift
from aatest.recording.dataset import StepData
from aatest.twin import model as m
from aatest.twin.api import simulate_dataset

FS_HZ = 2000.0


def _sine(sid: str, samples: int, cycles: int) -> PlannedStep:
    f = cycles * FS_HZ / samples
    return PlannedStep(id=sid, kind="sine", axis="inner", samples=samples, sample_rate_hz=FS_HZ,
                       duration_s=samples / FS_HZ, frequency_hz=f, accel_dps2=200.0)


def _twin_steps(drift_ppm: float, seed: int, samples: tuple[int, ...] = (16384,)
                ) -> list[StepData]:
    daq = m.DaqModel(clock_drift=m.ClockDrift(drift_ppm=drift_ppm), sync_edge_jitter_s=3e-6)
    rig = m.RigModel(sensors=[m.SensorModel(channel="v_sz", axis="I", noise_rms_v=0.001)],
                     daq=daq)
    steps = [_sine(f"s{i}", n, max(1, n // 2048)) for i, n in enumerate(samples)]
    return list(simulate_dataset(rig, steps, seed).steps)


def _table_with(data: StepData, **channels: np.ndarray) -> StepData:
    ch = {k: v for k, v in data.table.channels.items() if k not in channels}
    ch.update({k: v for k, v in channels.items() if v.size})
    return replace(data, table=SampledLog("table", data.table.sample_rate_hz,
                                          data.table.time_s, ch))


def _without_latch(data: StepData) -> StepData:
    return _table_with(data, fp_latch_s=np.array([]))


def _true_offset_s(data: StepData, drift_ppm: float) -> float:
    """The twin's trigger is DAQ sample 700 (0.35 s lead) and the table's first row."""
    trigger = int(np.argmax(np.asarray(data.daq["trigger"]) > 0.5))
    return -trigger / FS_HZ * (1.0 + drift_ppm * 1e-6)


@pytest.mark.parametrize("drift_ppm", [-150.0, 150.0])
def test_large_drift_without_latch_within_half_a_ppm(drift_ppm: float) -> None:
    """±150 ppm over 8.2 s: the edges cross table samples 2–3 times, which fixes the drift of
    each step to about a ppm (3 µs edge jitter blurs each crossing over ±2 edges); the three
    steps of one crystal together to within 0.5 ppm."""
    steps = _twin_steps(drift_ppm, seed=3, samples=(16384,) * 3)
    relations = [clock_relation(_without_latch(s)) for s in steps]
    for data, rel in zip(steps, relations, strict=True):
        assert not rel.latched and rel.edges_used > 800
        assert abs(rel.drift_ppm - drift_ppm) <= np.sqrt(3.0) * rel.drift_u_ppm  # inside the set
        # the trigger pins the offset; 1 µs: the DAQ stamps' line fit (6 µs jitter, 10⁴ stamps)
        assert abs(rel.offset_s - _true_offset_s(data, drift_ppm)) < 1e-6
    joint = joint_drift(relations)
    assert joint is not None and abs(joint[0] - drift_ppm) < 0.5
    assert clock_relation(steps[0]).latched


@pytest.mark.parametrize("drift_ppm", [26.3, -81.4, 4.7])
def test_small_drift_is_bounded_not_invented(drift_ppm: float) -> None:
    """Without a crossing the drift is only bounded: the truth lies in the stated range and
    the stated u says how wide it is (one sample over the record, ≈ 61 ppm at 8.2 s)."""
    data = _twin_steps(drift_ppm, seed=5)[0]
    rel = clock_relation(_without_latch(data))
    assert rel.slope_range is not None
    lo, hi = ((b - 1.0) * 1e6 for b in rel.slope_range)
    assert lo <= drift_ppm <= hi
    assert rel.drift_u_ppm == pytest.approx((hi - lo) / np.sqrt(12.0))
    assert hi - lo < 2.2 * 1e6 / FS_HZ / 8.192  # ≤ two samples over the record
    # alignment at the record's centre: within its stated interval (uniform: ±√3·u)
    mid = rel.record_mid_daq_s
    assert mid is not None
    true_mid = _true_offset_s(data, drift_ppm) + mid * (1 + drift_ppm * 1e-6)
    assert abs(rel.to_table_s(np.array(mid)) - true_mid) <= np.sqrt(3.0) * rel.offset_u_s


def test_a_long_step_fixes_the_drift_of_a_short_one() -> None:
    """Joint fit: one crystal, so the slopes every step allows intersect near the truth."""
    drift = 37.0
    steps = _twin_steps(drift, seed=7, samples=(4096, 65536))
    short, long_ = (clock_relation(_without_latch(s)) for s in steps)
    joint = joint_drift([short, long_])
    assert joint is not None
    assert short.drift_u_ppm > 40.0  # 2 s alone: one sample over the record
    # 33 s at 37 ppm: two crossings, each located to ±2 edges by the 3 µs jitter
    assert abs(joint[0] - drift) <= np.sqrt(3.0) * joint[1] and joint[1] < 1.0


def test_nan_latch_values_are_absent_per_edge() -> None:
    """NaN in ``fp_latch_s`` means "not latched": those edges drop out, the rest still latch."""
    drift = 61.0
    data = _twin_steps(drift, seed=9)[0]
    latch = np.array(data.table["fp_latch_s"], dtype=float)
    rows = rising_edges(data.table["sync_pulse"])
    gaps = latch.copy()
    gaps[rows[::3]] = np.nan  # every third edge not latched
    rel = clock_relation(_table_with(data, fp_latch_s=gaps))
    full = clock_relation(data)
    assert rel.latched and rel.edges_used == pytest.approx(full.edges_used * 2 / 3, abs=2)
    # latched edges: drift to the 3 µs jitter over 8 s, ≈0.05 ppm; 0.3 ppm is 6σ
    assert abs(rel.drift_ppm - drift) < 0.3
    all_nan = clock_relation(_table_with(data, fp_latch_s=np.full(latch.size, np.nan)))
    assert not all_nan.latched and np.isfinite(all_nan.drift_ppm)
    assert abs(all_nan.drift_ppm - drift) <= np.sqrt(3.0) * all_nan.drift_u_ppm


def test_one_sample_slips_are_corrected() -> None:
    """Edges registered one sample late in the first second (a vendor logger's slips) are
    found against their neighbours and undone: the fit is the unspoiled one."""
    drift = 15.0
    data = _without_latch(_twin_steps(drift, seed=11)[0])
    clean = clock_relation(data)
    pulse = np.array(data.table["sync_pulse"], dtype=float)
    rows = rising_edges(pulse)
    for r in rows[[5, 17, 40, 41]]:
        pulse[r] = 0.0  # the edge shows up on the next row
    slipped = clock_relation(_table_with(data, sync_pulse=pulse))
    assert slipped.slips_corrected >= 4
    assert slipped.drift_ppm == pytest.approx(clean.drift_ppm, abs=1e-6)
    assert slipped.offset_s == pytest.approx(clean.offset_s, abs=1e-9)


def test_a_short_step_refitted_inside_the_joint_range_takes_its_rate() -> None:
    """``clock_relation(..., slope_range=)``: the short step's relation is refitted inside the
    slopes all steps allow, so its drift is the joint one, not the centre of its own ±60 ppm."""
    drift = 37.0
    steps = [_without_latch(s) for s in _twin_steps(drift, seed=7, samples=(4096, 65536))]
    relations = [clock_relation(s) for s in steps]
    joint_range = joint_slope_range(relations)
    assert joint_range is not None
    short = clock_relation(steps[0], slope_range=joint_range)
    lo, hi = ((b - 1.0) * 1e6 for b in joint_range)
    assert lo <= short.drift_ppm <= hi
    # the joint range is under 2 ppm wide here (test above); the short step alone is > 40 ppm
    assert abs(short.drift_ppm - drift) < 2.0
    assert short.drift_u_ppm < 1.0
    assert relations[0].drift_u_ppm > 40.0
