"""The twin's logger converts as the rig description states (one source for the budget too)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml
from twin_steps import static_step

from aatest.engine.procedure.loader import RigConfig, load_rig
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


def test_a_stated_logger_converts_the_twin_built_from_a_model_file(tmp_path: Path) -> None:
    """The rig description states the logger for the twin of a model file too: before, the
    model file's converter (here ±10 V, 16 bit) quantised the data while the rail verdict
    and the budget read the stated one (0…5 V, 12 bit), so a clipping of the stated range
    never showed in the data. A model file's converter stays when no logger is stated."""
    model = realistic_rig_model()
    (tmp_path / "twin.yaml").write_text(yaml.safe_dump(model.model_dump(mode="json")))
    stated = "instruments:\n  logger: {bits: 12, range_v: [0, 5]}\n"
    unstated = "instruments:\n  thermometer: {accuracy_c: 0.1}\n"
    for instruments, expected in ((stated, (12, (0.0, 5.0))), (unstated, (16, (-10.0, 10.0)))):
        (tmp_path / "rig.yaml").write_text("daq: {plugin: sim, model: twin.yaml}\n" + instruments)
        rig = build_rig(load_rig(tmp_path / "rig.yaml"), SensorRef(model="sr207"), seed=0)
        world = rig.context.resources.setdefault(TwinSession, lambda: None).world
        assert (world.model.daq.adc_bits, tuple(world.model.daq.adc_range_v)) == expected
