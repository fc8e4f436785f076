"""On static data the scale factor is the datasheet's: the data cannot calibrate it.

The twin's realistic sr207 (g-sensitivity 0.573 (°/s²)/g, motor vibration on the table) at
six static positions. With the motor vibration in the model, the acceleration column of a
static record held only rounding residue, and its fitted coefficient — K = 2.1e134 V/(°/s²)
— was taken for the scale factor: the g-sensitivity came out as 1.1e-137 (°/s²)/g and that
K was written into ``--model-out``. The truth must now lie in the finding's 95 % interval,
and the written model must carry the datasheet's K.
"""

from __future__ import annotations

import json
from pathlib import Path

from typer.testing import CliRunner

from aatest.cli import app
from aatest.plugins.sensors.sr207 import SR207
from aatest.twin.defaults import realistic_rig_model
from aatest.twin.model import load_rig_model

PROCEDURE = """\
procedure: static-positions
sensor: {model: sr207, serial: "G1"}
rig: {turntable: sim, daq: sim, chamber: none}
sampling: {rate_hz: 2000, samples: 8000, settle_s: 1}
steps:
  - static: {inner_deg: 0, outer_deg: 0}
  - static: {inner_deg: 0, outer_deg: 180}
  - static: {inner_deg: 0, outer_deg: 90}
  - static: {inner_deg: 90, outer_deg: 90}
  - static: {inner_deg: 180, outer_deg: 90}
  - static: {inner_deg: 270, outer_deg: 90}
analysis: [sync, bias]
"""


def test_static_positions_give_the_g_sensitivity_with_the_datasheet_scale(tmp_path: Path
                                                                            ) -> None:
    sheet = SR207().datasheet()
    truth = realistic_rig_model(sheet).sensors[0].g_sensitivity
    assert truth is not None
    (tmp_path / "p.yaml").write_text(PROCEDURE, encoding="utf-8")
    run = CliRunner().invoke(app, ["run", str(tmp_path / "p.yaml"), "--out", str(tmp_path / "r"),
                                   "--seed", "3", "--no-progress"])
    assert run.exit_code == 0, run.output
    done = CliRunner().invoke(app, ["diagnose", str(tmp_path / "r"), "--json-out",
                                    str(tmp_path / "d.json"), "--model-out",
                                    str(tmp_path / "m.yaml")])
    assert done.exit_code in (0, 1), done.output  # 1: findings
    findings = {f["effect"]: f for f in json.loads((tmp_path / "d.json").read_text())["findings"]}
    low, high = findings["g_sensitivity"]["ci95"]["coefficient_dps2_per_g"]
    assert low <= truth.coefficient_dps2_per_g <= high, (low, high)
    assert high - low < 0.05  # six positions of 4 s resolve it to ±0.005 (°/s²)/g
    model = load_rig_model(tmp_path / "m.yaml")
    assert model.sensors[0].scale_v_per_dps2 == sheet.nominal_scale_v_per_dps2
