"""The example's effect plugin installed in this process, on data from independent physics.

The foreign-dataset generator (``foreign_dataset.py``) writes the asymmetric scale factor and
an even-order term from their physics, not through the twin; the twin case combines the plugin
effect with a built-in one. With ``asymmetric_scale`` installed: it is found (parameter within
25 %) alone and beside a built-in effect, it is *not* claimed for an even-order (α²) response
— whose structure stays in ``unexplained`` — and clean data give nothing at all.
"""

from __future__ import annotations

import json
import tomllib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from foreign_dataset import Hidden, write_dataset
from typer.testing import CliRunner

from aatest import effects as fx
from aatest.cli import app
from aatest.twin import model as m

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "vendor-plugin"

pytestmark = pytest.mark.slow


@pytest.fixture
def installed(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """The example distribution's entry points on ``sys.path`` (a ``.dist-info``)."""
    project = tomllib.loads((EXAMPLE / "pyproject.toml").read_text())["project"]
    info = tmp_path / "site" / "aatest_vendor_example-0.1.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(
        f"Metadata-Version: 2.1\nName: {project['name']}\nVersion: {project['version']}\n")
    (info / "entry_points.txt").write_text("".join(
        f"[{group}]\n" + "".join(f"{k} = {v}\n" for k, v in eps.items()) + "\n"
        for group, eps in project["entry-points"].items()))
    monkeypatch.syspath_prepend(str(tmp_path / "site"))
    monkeypatch.syspath_prepend(str(EXAMPLE / "src"))
    fx.refresh()
    assert "asymmetric_scale" in fx.installed_effects()
    yield
    monkeypatch.undo()
    fx.refresh()


def _diagnose(data: Path, *options: str) -> dict[str, Any]:
    out = data.parent / f"{data.name}.json"
    result = CliRunner().invoke(app, ["diagnose", str(data), "--json", str(out), *options])
    assert "Traceback" not in result.output, result.output
    return json.loads(out.read_text())


def _names(doc: dict[str, Any]) -> list[str]:
    return sorted(f["effect"] for f in doc["findings"])


@pytest.mark.usefixtures("installed")
@pytest.mark.parametrize("asymmetry", [-0.03, 0.012])
def test_found_on_independent_physics(tmp_path: Path, asymmetry: float) -> None:
    doc = _diagnose(write_dataset(tmp_path / "asym", Hidden("asymmetric_scale", asymmetry),
                                  samples=8192, seed=4))
    assert _names(doc) == ["asymmetric_scale"]
    assert doc["findings"][0]["parameters"]["asymmetry"] == pytest.approx(asymmetry, rel=0.25)
    assert doc["unexplained"] == []


@pytest.mark.usefixtures("installed")
def test_not_claimed_for_an_even_order_response(tmp_path: Path) -> None:
    doc = _diagnose(write_dataset(tmp_path / "even", Hidden("even_order", 0.05),
                                  samples=8192, seed=4))
    assert doc["findings"] == []
    assert [u["kind"] for u in doc["unexplained"]] == ["static_nonlinearity"]


@pytest.mark.usefixtures("installed")
def test_clean_data_give_nothing(tmp_path: Path) -> None:
    doc = _diagnose(write_dataset(tmp_path / "clean", Hidden(), samples=8192, seed=5))
    assert doc["findings"] == [] and doc["unexplained"] == []


@pytest.mark.usefixtures("installed")
def test_found_beside_a_builtin_effect(tmp_path: Path) -> None:
    """Twin data with the plugin effect and a bias temperature coefficient at once."""
    from aatest.diagnose.scenarios import clean_rig, diagnostic_plan
    from aatest.recording.data.exporter import export_csv
    from aatest.twin.api import simulate_dataset

    rig = clean_rig(9)
    sensor = rig.sensors[0].model_copy(update={
        "bias_temperature": m.BiasTemperature(coefficient_v_per_c=3e-4),
        "plugin_effects": [m.PluginEffect(effect="asymmetric_scale",
                                          distribution="aatest-vendor-example",
                                          parameters={"asymmetry": -0.015})]})
    data = tmp_path / "twin"
    export_csv(simulate_dataset(rig.model_copy(update={"sensors": [sensor]}),
                                diagnostic_plan(2**13), 9, procedure="plugin-pair"), data)
    model_out = tmp_path / "model.yaml"
    doc = _diagnose(data, "--model-out", str(model_out))
    assert _names(doc) == ["asymmetric_scale", "bias_temperature"]
    found = {f["effect"]: f["parameters"] for f in doc["findings"]}
    assert found["asymmetric_scale"]["asymmetry"] == pytest.approx(-0.015, rel=0.25)
    assert found["bias_temperature"]["coefficient_v_per_c"] == pytest.approx(3e-4, rel=0.25)
    assert doc["unexplained"] == []

    # the extended model, simulated by the twin (plugin forward model included) on a new seed,
    # reproduces the behaviour: diagnosing it finds the same effects and values again
    extended = m.load_rig_model(model_out)
    again = tmp_path / "again"
    export_csv(simulate_dataset(extended, diagnostic_plan(2**13), 19, procedure="again"), again)
    redo = _diagnose(again)
    assert _names(redo) == ["asymmetric_scale", "bias_temperature"]
    for f in redo["findings"]:
        for key, value in f["parameters"].items():
            assert value == pytest.approx(found[f["effect"]][key], rel=0.1), (f["effect"], key)
