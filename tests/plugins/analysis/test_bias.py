"""Static multi-position bias and g-sensitivity against synthetic truth."""

from __future__ import annotations

import pytest
from analyse import analyse
from synthetic_rig import SynthRig, SynthSensor, make_dataset, static_step

from aatest.plugins.analysis.bias import gravity_along_g


@pytest.mark.parametrize("axis, inner, outer, g", [("I", 0, 0, 1.0), ("I", 0, 180, -1.0),
                                                   ("O", 90, 90, 1.0), ("P", 0, 90, -1.0)],
                         ids=["I-up", "I-down", "O-up", "P-down"])
def test_gravity_frames(axis: str, inner: float, outer: float, g: float) -> None:
    assert gravity_along_g(axis, inner, outer) == pytest.approx(g, abs=1e-12)


def test_bias_and_g_sensitivity_recovered() -> None:
    sensors = (SynthSensor("v_sz", "I", bias_v=2.4987, g_dps2_per_g=0.6),
               SynthSensor("v_sy", "O", bias_v=2.5031, g_dps2_per_g=-0.4))
    positions = [(0, 0), (0, 180), (0, 90), (90, 90), (180, 90), (270, 90)]
    steps = [static_step(f"r{r}-{i}-{o}", i, o, repetition=r) for r in (1, 2, 3)
             for i, o in positions]
    out = analyse("bias", make_dataset(steps, SynthRig(sensors=sensors)))
    for s in sensors:
        v = out[s.channel]
        assert v["bias_v"] == pytest.approx(s.bias_v, abs=1e-4)
        assert v["g_sensitivity_dps2_per_g"] == pytest.approx(s.g_dps2_per_g, rel=0.1)
        assert "bias_within_datasheet" not in v  # pass/fail is the engine's verdict stage
        assert v["mountings"]["original"]["repetitions"] == 3
