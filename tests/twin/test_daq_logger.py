"""The twin's logger converts as the rig description states (one source for the budget too)."""

from __future__ import annotations

import numpy as np
from twin_steps import static_step

from aatest.engine.procedure.loader import RigConfig
from aatest.engine.rig_description import Instruments, LoggerSpec
from aatest.engine.run.rig import build_rig
from aatest.engine.steps import SensorRef
from aatest.twin.api import simulate_step
from aatest.twin.defaults import realistic_rig_model
from aatest.twin.session import TwinSession


def _codes(volts: np.ndarray, step_v: float, low_v: float) -> np.ndarray:
    """Recorded volts in converter steps above the range's low end."""
    return (np.asarray(volts) - low_v) / step_v


def test_default_twin_logger_is_the_stated_one() -> None:
    stated = LoggerSpec()  # ±10 V, 16 bit: 305 µV per step (what the budget's row states)
    daq = realistic_rig_model().daq
    assert (daq.adc_bits, tuple(daq.adc_range_v)) == (stated.bits, tuple(stated.range_v))
    sim = simulate_step(realistic_rig_model(), static_step(samples=4096), seed=2)
    codes = _codes(sim.daq["v_sz"], stated.step_v, stated.range_v[0])
    # every sample sits on the stated grid (rounding of float volts: 1e-6 of a step)
    assert np.max(np.abs(codes - np.round(codes))) < 1e-6
    # and uses it: adjacent codes are one step apart (not four 76 µV steps of a 0–5 V range)
    assert np.min(np.diff(np.unique(np.round(codes)))) == 1.0


def test_a_stated_logger_is_the_twins_logger() -> None:
    logger = LoggerSpec(bits=12, range_v=(0.0, 5.0))  # 1.22 mV per step
    rig = build_rig(RigConfig(instruments=Instruments(logger=logger)),
                    SensorRef(model="sr207"), seed=0)
    world = rig.context.resources.setdefault(TwinSession, lambda: None).world
    assert (world.model.daq.adc_bits, tuple(world.model.daq.adc_range_v)) == (12, (0.0, 5.0))
