"""More speed-ups of ``aatest diagnose`` that change no number (timings: ``bench/diagnose.py``).

* the single-frequency Lomb–Scargle power (the line search's) equals the grid periodogram;
* the memo of the commanded |rate| behind the stiction column stays short and exact;
* trigger alignment's uniform B-spline gives CubicSpline's values to rounding;
* the garbage-collector freeze around a diagnosis is undone after it, and leaves a caller's
  own freeze in place.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.interpolate import CubicSpline

from aatest.diagnose import design
from aatest.diagnose.periodogram import dft_at, lomb_scargle_at, lomb_scargle_power
from aatest.diagnose.replay import replay_dataset
from aatest.diagnose.scenarios import draw_hidden, scenario_dataset
from aatest.diagnose.spec import ChannelInfo, Spec
from aatest.diagnose.trigger_alignment import trigger_aligned

INFO = ChannelInfo("v_sz", "I", 572.958, 100.0, 25.0)


@pytest.fixture(scope="module")
def dataset():
    """The diagnostic plan (static, sines, ramps) at 2^12 samples per step, one hidden effect."""
    return scenario_dataset([draw_hidden("sensor_dynamics", 4)], seed=4, samples=2**12)


@pytest.mark.parametrize("f_hz", [0.31, 3.3, 47.123, 999.7])
def test_single_frequency_lomb_scargle_equals_the_grid_one(f_hz: float) -> None:
    rng = np.random.default_rng(11)
    t = 0.125 + 5e-4 * np.arange(2**14)
    y = 1e-3 * np.sin(2 * np.pi * f_hz * t + 0.3) + 1e-4 * rng.normal(size=t.size)
    y -= y.mean()
    grid = lomb_scargle_power(t, y, np.array([2 * np.pi * f_hz]))[0]
    # the same quadratic form of the same two sums, summed in another order: a few ulp of
    # sums over 2^14 terms (≈ 1e-12 relative), far inside 1e-9
    assert lomb_scargle_at(t, y, f_hz) == pytest.approx(grid, rel=1e-9)
    jittered = t + rng.normal(scale=1e-6, size=t.size)  # not uniform: direct sums
    direct = lomb_scargle_power(jittered, y, np.array([2 * np.pi * f_hz]))[0]
    assert lomb_scargle_at(jittered, y, f_hz) == pytest.approx(direct, rel=1e-9)


def test_dft_at_told_uniform_is_the_checked_sum() -> None:
    rng = np.random.default_rng(12)
    t = 0.25 + 5e-4 * np.arange(16387)
    values = rng.normal(size=t.size)
    for f_hz in (0.0, 3.3, 999.0):
        assert dft_at(values, t, f_hz, True) == dft_at(values, t, f_hz)  # the same arithmetic


def test_stiction_rate_memo_is_short_and_exact(dataset) -> None:
    replay = replay_dataset(dataset)
    sr = next(s for s in replay.steps if s.dynamic)
    spec = Spec(linear=frozenset({"rotor_stiction"}), stiction_dps=5.0)
    for k in range(3 * design.RATE_MEMO):
        shifted = replace(spec, delay_s=1e-4 * k)
        cached = design._design(sr, INFO, shifted, {"rotor_stiction"})["rotor_stiction"]
        sr.memo.clear()  # nothing memoised: the column computed from scratch
        fresh = design._design(sr, INFO, shifted, {"rotor_stiction"})["rotor_stiction"]
        assert np.array_equal(cached, fresh)
        again = design._design(sr, INFO, replace(shifted, stiction_dps=9.0), {"rotor_stiction"})
        sr.memo.clear()
        assert np.array_equal(again["rotor_stiction"], design._design(
            sr, INFO, replace(shifted, stiction_dps=9.0), {"rotor_stiction"})["rotor_stiction"])
        assert np.any(again["rotor_stiction"] != cached)  # a wider gap: another column
    for k in range(3 * design.RATE_MEMO):
        design._design(sr, INFO, replace(spec, delay_s=1e-4 * k), {"rotor_stiction"})
    assert sum(1 for key in sr.memo if key[0] == "abs rate") <= design.RATE_MEMO


def test_trigger_alignment_resamples_as_cubic_spline(dataset) -> None:
    data = next(d for d in dataset.steps if d.step.recorded and d.step.kind == "sine")
    synced = trigger_aligned(data)
    assert synced is not None
    daq = data.daq
    daq_t = float(daq.time_s[0]) + np.arange(daq.time_s.size) / daq.sample_rate_hz
    at_daq = synced.relation.to_daq_s(np.asarray(synced.time_s, dtype=float))
    volts = np.asarray(daq["v_sz"], dtype=float)
    expected = CubicSpline(daq_t, volts)(at_daq)
    # the two interpolate the same samples with the same end conditions; they differ by the
    # rounding of the knot times (t0 + k/fs, ≈ 1e-16 of t0 each) carried through the slope:
    # ≈ 1e-13 of the signal's range, well inside 1e-10
    assert_allclose(synced.daq["v_sz"], expected, rtol=0, atol=1e-10 * np.ptp(volts))
