"""The example's effect plugin (``asymmetric_scale``, group ``aatest.effects``) end to end.

A dataset is generated from the physics — the twin with the plugin's forward model switched on
in its rig model, seeded — and exported in the import format, inside a fresh venv where the
example is installed by pip. There ``aatest diagnose`` names the plugin effect with its
parameter and writes it into ``--model-out``; in this process, where the example is not
installed, the same data's structure is reported in ``unexplained`` (kind ``asymmetry``) and no
vocabulary name is forced onto it; and the model file that needs the plugin is refused with
exit 2 naming the effect and the distribution to install.
"""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from aatest.cli import app
from aatest.effects import installed_effects
from aatest.engine.errors import EXIT_BAD_INPUT, EXIT_FINDING

ASYMMETRY = 0.02
SEED = 11
SAMPLES = 2**12
#: the generator the venv runs: twin + plugin forward model → import directory
GENERATE = """\
import sys
from pathlib import Path
from aatest.diagnose.scenarios import clean_rig, diagnostic_plan
from aatest.recording.data.exporter import export_csv
from aatest.twin.api import simulate_dataset
from aatest.twin.model import PluginEffect

asymmetry, seed, samples, out = float(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
rig = clean_rig(seed)
effect = PluginEffect(effect="asymmetric_scale", distribution="aatest-vendor-example",
                      parameters={"asymmetry": asymmetry})
sensor = rig.sensors[0].model_copy(update={"plugin_effects": [effect]})
rig = rig.model_copy(update={"sensors": [sensor]})
export_csv(simulate_dataset(rig, diagnostic_plan(samples), seed, procedure="plugin-effect"),
           Path(out))
"""


def _venv_run(scripts: Path, *args: str | Path, cwd: Path) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    return subprocess.run([str(a) for a in args], cwd=cwd, env=env, check=False,
                          capture_output=True, text=True, timeout=600)


@pytest.fixture(scope="module")
def dataset(vendor_venv: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The import directory generated with the plugin effect switched on (in the venv)."""
    root = tmp_path_factory.mktemp("asymmetric")
    script = root / "generate.py"
    script.write_text(GENERATE)
    out = root / "import"
    done = _venv_run(vendor_venv, vendor_venv / "python", script, str(ASYMMETRY), str(SEED),
                     str(SAMPLES), out, cwd=root)
    assert done.returncode == 0, done.stdout + done.stderr
    return out


@pytest.fixture(scope="module")
def with_plugin(vendor_venv: Path, dataset: Path) -> tuple[int, dict[str, Any], Path]:
    """``aatest diagnose`` in the venv where the example is installed."""
    json_out, model_out = dataset.parent / "with.json", dataset.parent / "model.yaml"
    done = _venv_run(vendor_venv, vendor_venv / "aatest", "diagnose", dataset, "--json",
                     json_out, "--model-out", model_out, cwd=dataset.parent)
    assert "Traceback" not in done.stderr, done.stderr
    return done.returncode, json.loads(json_out.read_text()), model_out


def test_listed_as_an_effect_plugin(vendor_venv: Path, tmp_path: Path) -> None:
    done = _venv_run(vendor_venv, vendor_venv / "aatest", "plugins", cwd=tmp_path)
    assert done.returncode == 0, done.stdout + done.stderr
    section = done.stdout.split("effect:")[1].splitlines()
    assert ["asymmetric_scale", "aatest-vendor-example", "0.1.0"] in [s.split() for s in section]


def test_found_when_installed(with_plugin: tuple[int, dict[str, Any], Path]) -> None:
    code, doc, _ = with_plugin
    assert code == EXIT_FINDING
    assert [f["effect"] for f in doc["findings"]] == ["asymmetric_scale"]
    [finding] = doc["findings"]
    assert finding["parameters"]["asymmetry"] == pytest.approx(ASYMMETRY, rel=0.25)
    lo, hi = finding["ci95"]["asymmetry"]
    assert lo < finding["parameters"]["asymmetry"] < hi and lo > 0
    assert finding["plugin"]["distribution"] == "aatest-vendor-example"
    # the backward pass re-tests it in the joint model: removing it alone costs evidence
    assert finding["marginal"]["delta_bic"] < -10.0
    assert doc["unexplained"] == []  # the plugin explains the structure: nothing left over
    assert doc["gain"]["reduction_pct"] > 50.0
    report = with_plugin[2].parent / "diagnosis.html"  # rendered next to the JSON
    assert "asymmetric_scale" in report.read_text(encoding="utf-8")


def test_model_out_names_the_plugin(with_plugin: tuple[int, dict[str, Any], Path]) -> None:
    from ruamel.yaml import YAML

    _, doc, model_out = with_plugin
    model = YAML(typ="safe").load(model_out.read_text())
    [effect] = model["sensors"][0]["plugin_effects"]
    assert effect["effect"] == "asymmetric_scale"
    assert effect["distribution"] == "aatest-vendor-example"
    assert effect["parameters"]["asymmetry"] == doc["findings"][0]["parameters"]["asymmetry"]


def test_unexplained_when_not_installed(dataset: Path) -> None:
    assert "asymmetric_scale" not in installed_effects()  # this process never installed it
    out = dataset.parent / "without" / "without.json"
    out.parent.mkdir()
    result = CliRunner().invoke(app, ["diagnose", str(dataset), "--json", str(out)])
    assert "Traceback" not in result.output
    doc = json.loads(out.read_text())
    assert doc["findings"] == []  # no wrong vocabulary name
    kinds = [u["kind"] for u in doc["unexplained"]]
    assert kinds == ["asymmetry"], doc["unexplained"]
    # the generic |α| extension reads d = a/2 (docs/interfaces.md §4 unexplained)
    assert doc["unexplained"][0]["extension"]["d"] == pytest.approx(ASYMMETRY / 2, rel=0.25)


def test_model_needing_a_missing_plugin_is_refused(
        with_plugin: tuple[int, dict[str, Any], Path], tmp_path: Path) -> None:
    _, _, model_out = with_plugin
    from aatest.twin.model import load_rig_model

    with pytest.raises(Exception) as info:
        load_rig_model(model_out)
    err = info.value
    assert getattr(err, "exit_code", None) == EXIT_BAD_INPUT
    assert "'asymmetric_scale' is not installed" in str(err)
    assert "install the distribution 'aatest-vendor-example'" in str(err)
    assert f"{model_out}:" in str(err)  # located: FILE:LINE:COLUMN
