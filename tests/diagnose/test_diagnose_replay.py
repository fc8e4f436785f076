"""Replay: the commanded motion aligned on the table log; the nominal residual at noise level."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from aatest.diagnose.alignment import nominal_fit
from aatest.diagnose.candidates.base import Context
from aatest.diagnose.replay import fit_axis_motion, replay_dataset
from aatest.diagnose.scenarios import scenario_dataset
from aatest.diagnose.spec import ChannelInfo


def test_fit_axis_motion_recovers_sine_and_ramp() -> None:
    t = np.arange(4096) / 2000.0
    w = 2 * np.pi * 1.953125
    pos = 3.0 + 2.0 * np.sin(w * t) - 0.5 * np.cos(w * t)
    m = fit_axis_motion(t, pos, True, 1.953125, False)
    assert_allclose([m.offset_deg, m.sin_deg, m.cos_deg], [3.0, 2.0, -0.5], atol=1e-9)
    ramp = fit_axis_motion(t, 1.0 + 30.0 * t, True, None, True)
    assert_allclose([ramp.offset_deg, ramp.rate_dps], [1.0, 30.0], atol=1e-9)
    _angle, _rate, accel = m.evaluate(t)
    assert_allclose(accel, -(w**2) * (pos - 3.0), atol=1e-9)


@pytest.fixture(scope="module")
def clean_replay():
    return replay_dataset(scenario_dataset([], seed=11, samples=2**13))


def test_nominal_residual_is_the_sensor_noise(clean_replay) -> None:
    """With the logger filter in the chain, the nominal replay leaves only the 1 mV noise."""
    targets = {s.index: s.volts["v_sz"] for s in clean_replay.steps}
    info = ChannelInfo("v_sz", "I", 572.958, 100.0, 25.0)
    fit = nominal_fit(Context(clean_replay, info, targets, None))
    assert_allclose(fit.scale, 0.004014, rtol=1e-3)
    assert abs(fit.spec.delay_s) <= clean_replay.dt_s  # the sync's sub-sample alignment
    assert_allclose(np.sqrt(fit.sse_held_out / fit.n), 0.001, rtol=0.05)
