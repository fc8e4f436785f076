"""Logger clocks and the freeze-pulse method (docs/method.md §2, docs/interfaces.md §4 "Clocks")."""

from __future__ import annotations

import numpy as np
from numpy.testing import assert_allclose
from twin_steps import static_step

from aatest.twin.api import realistic_rig_model, simulate_step
from aatest.twin.step_setup import SimulatedStep


def rising_rows(pulse: np.ndarray) -> np.ndarray:
    """Indices where a 0/1 pulse goes 0 → 1."""
    p = np.asarray(pulse)
    return np.flatnonzero((p[1:] > 0.5) & (p[:-1] < 0.5)) + 1


def daq_and_table_edges(sim: SimulatedStep) -> tuple[np.ndarray, np.ndarray]:
    """Matched rising edges: DAQ time stamps and latch-corrected table times."""
    d_rows = rising_rows(sim.daq["sync_pulse"])
    t_rows = rising_rows(sim.table["sync_pulse"])
    t_table = sim.table.time_s[t_rows] - np.asarray(sim.table["fp_latch_s"])[t_rows]
    t_daq_all = np.asarray(sim.daq.time_s)[d_rows]
    # pair each table edge with the DAQ edge at the same lab time (within half a period)
    lab_of_daq = np.asarray(sim.truth["daq_time_s"])[d_rows]
    idx = np.searchsorted(lab_of_daq, t_table - 0.005)
    return t_daq_all[idx], t_table


def _without_edge_jitter(drift_ppm: float):
    model = realistic_rig_model(drift_ppm=drift_ppm)
    return model.model_copy(
        update={"daq": model.daq.model_copy(update={"sync_edge_jitter_s": 0.0})}
    )


def test_freeze_pulse_registered_one_cycle_late_with_latch_time() -> None:
    model = _without_edge_jitter(0.0)
    sim = simulate_step(model, static_step(samples=8192), seed=21)
    dt = 1 / 2000
    rows = rising_rows(sim.table["sync_pulse"])
    latch = np.asarray(sim.table["fp_latch_s"])[rows]
    true_edge = sim.table.time_s[rows] - latch
    # the true edges are the DAQ's: 100 Hz on the DAQ clock (drift 0 here)
    assert_allclose(np.diff(true_edge), 0.01, atol=1e-9)
    # registered one logging cycle late: between 1 and 2 sample periods after the true edge
    assert np.all(latch >= dt - 1e-12) and np.all(latch < 2 * dt)
    # the DAQ sees the same edge on its first sample at or after it (no cycle of delay)
    d_rows = rising_rows(sim.daq["sync_pulse"])
    daq_edge_table_time = np.asarray(sim.truth["daq_time_s"])[d_rows]
    lag = sim.table.time_s[rows][:, None] - daq_edge_table_time[None, :]
    nearest = lag[np.arange(len(rows)), np.argmin(np.abs(lag), axis=1)]
    assert_allclose(nearest, dt, atol=1e-9)  # exactly one sample later than the DAQ


def test_100_ppm_clock_error_is_a_linear_drift_of_sync_edges() -> None:
    model = realistic_rig_model(drift_ppm=100.0)
    sim = simulate_step(model, static_step(samples=60000), seed=22)
    t_daq, t_table = daq_and_table_edges(sim)
    gap = t_table - t_daq
    fit = np.polyfit(t_daq, gap, 1)
    assert_allclose(fit[0] * 1e6, 100.0, atol=1.0)  # 100 µs per second
    residual = gap - np.polyval(fit, t_daq)
    assert np.std(residual) < 2e-4  # sample quantisation (≤ 0.5 ms) + 6 µs jitter
    assert sim.truth["drift_ppm"] == 100.0


def test_daq_starts_earlier_stops_later_and_triggers_the_table() -> None:
    model = realistic_rig_model()
    sim = simulate_step(model, static_step(samples=4096), seed=23)
    daq_lab = np.asarray(sim.truth["daq_time_s"])
    assert daq_lab[0] < -0.3 and daq_lab[-1] > sim.table.time_s[-1] + 0.3
    first = int(np.argmax(np.asarray(sim.daq["trigger"]) > 0.5))
    assert_allclose(daq_lab[first], 0.0, atol=1e-9)  # trigger = first table sample
    assert np.all(np.asarray(sim.daq["trigger"])[:first] == 0.0)
    # the contract's clock relation holds: t_table = offset + t_daq·(1 + drift·1e-6)
    predicted = sim.truth["offset_s"] + np.asarray(sim.daq.time_s) * (
        1 + sim.truth["drift_ppm"] * 1e-6
    )
    assert np.std(predicted - daq_lab) < 10e-6  # only the 6 µs time-stamp jitter remains
    pulse = np.asarray(sim.daq["sync_pulse"])
    assert set(np.unique(pulse)) == {0.0, 1.0}
    assert_allclose(np.mean(pulse), 0.5, atol=0.01)  # 10 samples high, 10 low


def test_clock_relation_residual_is_a_few_microseconds() -> None:
    """Latch-corrected table edges vs the DAQ clock: residual σ ≈ 2.4–3.5 µs (docs/method.md §2)."""
    sim = simulate_step(realistic_rig_model(), static_step(samples=20000), seed=24)
    d_rows = rising_rows(sim.daq["sync_pulse"])
    t_rows = rising_rows(sim.table["sync_pulse"])
    t_table = sim.table.time_s[t_rows] - np.asarray(sim.table["fp_latch_s"])[t_rows]
    # DAQ edge times from its sample clock (index / rate): the jittered stamps are not needed
    t_daq = d_rows / sim.daq.sample_rate_hz
    lab_of_daq = np.asarray(sim.truth["daq_time_s"])[d_rows]
    t_daq = t_daq[np.searchsorted(lab_of_daq, t_table - 0.005)]
    residual = t_table - np.polyval(np.polyfit(t_daq, t_table, 1), t_daq)
    assert 2.4e-6 <= np.std(residual) <= 3.5e-6


def test_both_loggers_follow_the_step_rate() -> None:
    step = static_step(samples=2048).model_copy(update={"sample_rate_hz": 1000.0})
    sim = simulate_step(realistic_rig_model(), step, seed=25)
    assert sim.table.sample_rate_hz == sim.daq.sample_rate_hz == 1000.0
    assert_allclose(np.diff(sim.table.time_s), 1e-3)
    rows = rising_rows(sim.table["sync_pulse"])
    assert_allclose(
        np.diff(sim.table.time_s[rows] - np.asarray(sim.table["fp_latch_s"])[rows]), 0.01, atol=2e-5
    )  # 100 Hz edges, ±3 µs jitter
