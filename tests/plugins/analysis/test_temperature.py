"""Temperature coefficients and hysteresis against the twin and synthetic truth."""

from __future__ import annotations

import numpy as np
import pytest
from analyse import analyse
from synthetic_rig import sine_step, static_step
from twin_helpers import twin_dataset

from aatest.plugins.analysis.temperature import hysteresis_v

SEQUENCE_C = [22, 7.5, -2, -11, -21, -14, -5, 4, 20, 29, 38, 48, 38, 29, 22]


def test_hysteresis_between_branches() -> None:
    temps = np.array([20.0, 0.0, -20.0, 0.0, 20.0])
    values = np.array([1.0, 1.0, 1.0, 1.002, 1.002])
    assert hysteresis_v(temps, values) == pytest.approx(0.002, abs=1e-9)


def test_coefficients_against_twin(realistic_unit) -> None:  # type: ignore[no-untyped-def]
    model = realistic_unit.model_copy(update={"sensors": realistic_unit.sensors[:1]})
    static = [static_step(f"t{i}", 0, 0, samples=4096, temperature_c=t, settle_s=1.0)
              for i, t in enumerate(SEQUENCE_C)]
    sine = [sine_step(f"s{i}", 8, 400.0, samples=8192, temperature_c=t, settle_s=1.0)
            for i, t in enumerate(SEQUENCE_C[::3])]
    temps = SEQUENCE_C + SEQUENCE_C[::3]
    data, _ = twin_dataset(model, static + sine, temperatures_c=temps)
    v = analyse("temperature", data)["v_sz"]
    s = model.sensors[0]
    assert v["bias_coefficient_v_per_c"] == pytest.approx(
        s.bias_temperature.coefficient_v_per_c, rel=0.1)
    assert v["scale_coefficient_per_c"] == pytest.approx(
        s.scale_temperature.coefficient_per_c, rel=0.1)
    assert v["hysteresis_v"] is not None and v["hysteresis_v"] < 2e-4
    assert "bias_coefficient_within_datasheet" not in v  # pass/fail: the engine's verdicts
    lo, hi = v["bias_coefficient_ci95_v_per_c"]
    assert lo < s.bias_temperature.coefficient_v_per_c < hi or abs(hi - lo) < 2e-5
