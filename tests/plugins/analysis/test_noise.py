"""Noise: band RMS and Allan white-noise term against known white noise."""

from __future__ import annotations

import numpy as np
import pytest
from analyse import analyse
from synthetic_rig import SynthRig, SynthSensor, make_dataset, static_step
from twin_helpers import twin_dataset

from aatest.engine.analysis.passes import run_analysis


def test_white_noise_figures() -> None:
    sensor = SynthSensor(noise_v=0.001)
    data = make_dataset([static_step("n", 0, 0, samples=32768)], SynthRig(sensors=(sensor,)))
    out = run_analysis("noise", data)
    v = out.result["v_sz"].model_dump()
    assert v["rms_v"] == pytest.approx(0.001 * np.sqrt(400 / 1000), rel=0.05)
    white = 0.001 / sensor.scale_v_per_dps2 / np.sqrt(2000.0)
    assert v["allan_dps2"]["white_noise_per_sqrt_hz"] == pytest.approx(white, rel=0.1)
    assert "within_datasheet" not in v and "noise_v_sz" in out.figures  # verdicts: engine


def test_noise_against_twin_motor_off(realistic_unit) -> None:  # type: ignore[no-untyped-def]
    model = realistic_unit.model_copy(update={"sensors": realistic_unit.sensors[:1]})
    data, _ = twin_dataset(model, [static_step("n", 0, 0, samples=16384, motor_on=False)])
    v = analyse("noise", data)["v_sz"]
    # 1 mV RMS recorded behind the 100 Hz pre-sample filter: all of it below 400 Hz
    assert v["rms_v"] == pytest.approx(model.sensors[0].noise_rms_v, rel=0.1)
