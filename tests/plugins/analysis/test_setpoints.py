"""Bias and scale factor per chamber set-point, each certified and judged (issue 32).

The QA engineer's temperature campaign: −20, +25 and +60 °C, a ±1 g pair and a 1 Hz sine at
each. Nothing mixes temperatures: the headline values are the 25 °C set-point's and say so,
and the other set-points follow the twin's known bias and scale temperature coefficients.
"""

from __future__ import annotations

import json
import math
from typing import Any

import pytest
from typer.testing import CliRunner

from aatest.cli import app
from aatest.engine.procedure.planner import default_datasheet
from aatest.twin.defaults import realistic_sensor_model

SETPOINTS_C = (-20.0, 25.0, 60.0)
PROCEDURE = """\
procedure: temperature-campaign
sensor: {model: sr207, serial: "T1"}
rig: {turntable: sim, daq: sim, chamber: sim}
sampling: {rate_hz: 2000, samples: 8000, settle_s: 1}
steps:
  - temperature_steps:
      setpoints_c: [-20, 25, 60]
      soak_s: 600
      off_wait_s: 10
      static: true
      bias_pair: true
      dynamic: {axis: inner, frequency_hz: 1.0, accel_dps2: 400}
analysis: [sync, bias, scale_factor, temperature]
acceptance:
  limits: {bias_deviation_v: 0.05}
  judge: [bias_deviation_v, scale_factor_deviation_pct, bias_temperature_v_per_c,
          scale_temperature_per_c]
"""


@pytest.fixture(scope="module")
def campaign(tmp_path_factory: pytest.TempPathFactory) -> tuple[int, dict[str, Any]]:
    tmp = tmp_path_factory.mktemp("campaign")
    (tmp / "campaign.yaml").write_text(PROCEDURE, encoding="utf-8")
    done = CliRunner().invoke(app, ["run", str(tmp / "campaign.yaml"), "--out", str(tmp / "run"),
                                    "--no-progress", "--seed", "9"])
    return done.exit_code, json.loads((tmp / "run" / "results.json").read_text())


def _truth() -> tuple[float, float]:
    """The twin's bias (V/°C) and scale (1/°C) temperature coefficients of v_sz."""
    model = realistic_sensor_model(default_datasheet("sr207"), "v_sz", "I")
    assert model.bias_temperature is not None and model.scale_temperature is not None
    return model.bias_temperature.coefficient_v_per_c, model.scale_temperature.coefficient_per_c


def test_bias_per_setpoint_follows_the_twins_coefficient(
        campaign: tuple[int, dict[str, Any]]) -> None:
    """b(T) − b(25 °C) = c_b·(T − 25): 13.5 mV at −20 °C. Tolerance: the two set-points'
    expanded uncertainties combined (conservative: the logger's offset and gain in them cancel
    in the difference); mixing the temperatures would give ≈ 0 and fail."""
    code, results = campaign
    assert code == 0 and results["overall"] == "pass"
    bias_tc, _scale_tc = _truth()
    head = results["analysis"]["bias"]["v_sz"]
    assert head["temperature_c"] == 25.0
    points = {p["temperature_c"]: p for p in head["setpoints"]}
    assert tuple(points) == SETPOINTS_C
    for t in (-20.0, 60.0):
        step = points[t]["bias_v"] - head["bias_v"]
        tol = math.hypot(points[t]["expanded_uncertainty"], head["expanded_uncertainty"])
        assert abs(step - bias_tc * (t - 25.0)) <= tol, (t, step)
    judged = {v["channel"] for v in results["verdicts"] if v["quantity"] == "bias_deviation_v"}
    assert judged == {"v_sz", "v_sz at -20 °C", "v_sz at 60 °C"}


def test_scale_factor_per_setpoint_follows_the_twins_coefficient(
        campaign: tuple[int, dict[str, Any]]) -> None:
    """K(T)/K(25 °C) − 1 = c_K·(T − 25) (−0.9 % at −20 °C), within 3 × the two levels'
    combined Type A relative u (≈ 1e-4: the 4 s records' fit)."""
    _code, results = campaign
    _bias_tc, scale_tc = _truth()
    head = results["analysis"]["scale_factor"]["v_sz"]
    assert (head["accel_dps2"], head["temperature_c"]) == (400.0, 25.0)
    levels = {lv["temperature_c"]: lv for lv in head["levels"]}
    assert tuple(levels) == SETPOINTS_C
    for t in (-20.0, 60.0):
        low, ref = levels[t], levels[25.0]
        ratio = low["scale_v_per_dps2"] / ref["scale_v_per_dps2"] - 1.0
        u = math.hypot(low["scale_u_v_per_dps2"] / low["scale_v_per_dps2"],
                       ref["scale_u_v_per_dps2"] / ref["scale_v_per_dps2"])
        assert abs(ratio - scale_tc * (t - 25.0)) <= 3 * u, (t, ratio)
