"""Block-by-block reductions of a long record equal the whole-array computations.

Each reduction is fed the record in uneven blocks (block boundaries fall anywhere, as the
recording's pieces do) and compared with numpy/scipy on the whole array. Tolerances: sums of
10⁵–10⁶ float64 terms in a different order differ by a few ulp per term at most (rel 1e-12
leaves three orders of magnitude); the time line's slope is a ratio of co-moments summed in
a different order (rel 1e-9).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from aatest.clocksync.freeze_pulse import rising_edges, synchronise
from aatest.clocksync.streamed import log_pieces, scan_daq
from aatest.engine.interfaces import TableEnvelope
from aatest.engine.logs import SampledLog
from aatest.engine.procedure.envelope import head_step
from aatest.engine.steps import PlannedStep
from aatest.plugins.analysis.streaming import Moments, StreamedWelch, allan_block
from aatest.recording.dataset import StepData
from aatest.twin.defaults import realistic_rig_model
from aatest.twin.world import World

RNG = np.random.default_rng(26)


def _blocks(values: np.ndarray) -> list[np.ndarray]:
    cuts = np.sort(RNG.choice(np.arange(1, values.size), size=7, replace=False))
    return np.split(values, cuts)


def test_moments_and_welch_in_blocks_equal_the_whole_record() -> None:
    volts = 2.5 + 1e-3 * RNG.standard_normal(300_001)
    moments, welch = Moments(), StreamedWelch(2000.0, volts.size)
    for block in _blocks(volts):
        moments.add(block)
        welch.add(block)
    assert moments.mean == pytest.approx(np.mean(volts), rel=1e-12)
    assert moments.std == pytest.approx(np.std(volts), rel=1e-9)
    f, psd = welch.result()
    f_ref, psd_ref = signal.welch(volts - volts.mean(), fs=2000.0, nperseg=2**13,
                                  detrend="constant")
    assert np.array_equal(f, f_ref)
    np.testing.assert_allclose(psd, psd_ref, rtol=1e-9)


def test_allan_means_stay_bounded() -> None:
    assert allan_block(2**18) == 1
    assert allan_block(8 * 3600 * 2000) * 2**18 >= 8 * 3600 * 2000  # 8 h: ≤ 2^18 means


def test_scan_finds_the_edges_and_time_line_of_the_whole_log() -> None:
    n, fs = 400_000, 2000.0
    index = np.arange(n)
    time_s = 3.0 + index / fs * (1 + 12e-6) + 6e-6 * RNG.standard_normal(n)
    pulse = ((index // 10) % 2 == 0).astype(float)
    trigger = (index >= 700).astype(float)
    log = SampledLog("daq", fs, time_s, {"sync_pulse": pulse, "trigger": trigger}, {})
    scan = scan_daq(log_pieces(log, per=65_537)(None), keep_edges_s=1e9)
    assert np.array_equal(scan.edges, rising_edges(pulse))
    assert scan.trigger == 700 and scan.samples == n
    slope, _ = np.polyfit(index, time_s - time_s[0], 1)
    assert scan.time_fit[1] == pytest.approx(slope, rel=1e-9)


def test_a_record_longer_than_the_table_log_is_synchronised_whole() -> None:
    """3 min on the twin: the table holds the first 115 s; the synchronised record is the
    whole DAQ record from the trigger to the planned end, its mean the whole record's."""
    step = PlannedStep(id="s001-static-long", kind="static", samples=360_000, duration_s=180.0,
                       settle_s=5.0, motor_on=False)
    world = World(realistic_rig_model(), seed=3)
    world.move_to(0.0, 0.0)
    world.begin_motion(step)
    world.start_daq()
    daq = world.result().daq
    table = world.snapshot_log(head_step(step, TableEnvelope()))
    synced = synchronise(StepData(step, table, daq))
    assert synced.record is not None and len(table) == 230_000
    trigger = int(np.flatnonzero(daq["trigger"] > 0.5)[0])
    # the planned 180 s of the table clock on the DAQ clock (12 ppm apart), ±1 sample each end
    drift = synced.relation.drift_ppm * 1e-6
    assert drift == pytest.approx(12e-6, abs=0.01e-6)
    assert len(synced) == pytest.approx(360_000 / (1 + drift), abs=2)
    assert synced.record.first == pytest.approx(trigger, abs=1)
    assert synced.relation.fit_coverage == pytest.approx(115.0 / 180.0, rel=0.01)
    mean = Moments()
    for block in synced.daq_blocks(["v_sz"]):
        mean.add(block["v_sz"])
    whole = daq["v_sz"][synced.record.first:synced.record.stop]
    assert mean.n == whole.size and mean.mean == pytest.approx(np.mean(whole), rel=1e-12)
