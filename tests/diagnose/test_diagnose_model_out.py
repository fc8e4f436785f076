"""``--model-out``: the extended model, loaded by the twin, reproduces the measured behaviour."""

from __future__ import annotations

import contextlib
import io

import numpy as np

from aatest.diagnose.command import diagnose_command
from aatest.diagnose.scenarios import diagnostic_plan, draw_hidden, scenario_dataset
from aatest.recording.data.exporter import export_csv
from aatest.twin.api import simulate_dataset
from aatest.twin.model import load_rig_model

SAMPLES = 2**13


def test_rerun_with_the_extended_model_reproduces_the_data(tmp_path) -> None:
    """Same plan and seed on the extended model: the sensor record matches to ≪ the noise."""
    seed = 4
    measured = scenario_dataset([draw_hidden("sensor_dynamics", seed)], seed, SAMPLES)
    export_csv(measured, tmp_path / "import")
    with contextlib.redirect_stdout(io.StringIO()):
        findings = diagnose_command(tmp_path / "import", tmp_path / "d.json", tmp_path / "m.yaml")
    assert [f["effect"] for f in findings] == ["sensor_dynamics"]
    model = load_rig_model(tmp_path / "m.yaml")
    assert model.sensors[0].sensor_dynamics is not None
    rerun = simulate_dataset(model, diagnostic_plan(SAMPLES), seed)
    for a, b in zip(measured.steps, rerun.steps, strict=True):
        n = min(len(a.daq), len(b.daq))
        diff_v = np.std(a.daq["v_sz"][:n] - b.daq["v_sz"][:n])
        assert diff_v < 2e-4, a.step.id  # the 1 mV noise draws coincide; the model does too
