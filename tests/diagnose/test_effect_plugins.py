"""Effect plugins (entry-point group ``aatest.effects``): validation, vocabulary, twin, model.

Plugins are installed the light way — a ``.dist-info`` with entry points on ``sys.path`` —
pointing at the classes of this module, so each test controls exactly which distributions
declare which effects. The twin's forward model and the diagnose fit are checked against the
physics the plugin states (known parameters in, same parameters out).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from aatest import effects as fx
from aatest.cli import app
from aatest.diagnose.candidates import CANDIDATES, vocabulary
from aatest.diagnose.model_out import extended_model
from aatest.effects import Effect, EffectInputs, EffectParameter, Excitation
from aatest.engine.errors import EXIT_BAD_INPUT, PluginError
from aatest.twin import model as m
from aatest.twin.sensor import SensorInputs, output_volts

HERE = Path(__file__).resolve().parent
EXAMPLE_SRC = HERE.parents[1] / "examples" / "vendor-plugin" / "src"


class SettlingBias(Effect):
    """Bias settling after the record starts: v += A·exp(−t/τ) (a warm-up transient)."""

    name = "settling_bias"
    parameters = (EffectParameter("amplitude_v", "V"),)
    shape_parameters = (EffectParameter("time_constant_s", "s", lower=0.05, upper=2.0),)
    enters = "voltage"

    def columns(self, inputs: EffectInputs, shape: Mapping[str, float]) -> dict[str, np.ndarray]:
        t = np.clip(inputs.time_s, 0.0, None)
        return {"amplitude_v": np.exp(-t / shape["time_constant_s"])}

    def testable(self, excitation: Excitation) -> str | None:
        return None


class EvenSquare(Effect):
    """α_out = α + c2·α²/α_range (a lab's even-order term)."""

    name = "even_square"
    parameters = (EffectParameter("c2", "1"),)

    def columns(self, inputs: EffectInputs, shape: Mapping[str, float]) -> dict[str, np.ndarray]:
        return {"c2": inputs.alpha_dps2**2 / inputs.range_dps2}


class NoUnit(EvenSquare):
    name = "no_unit"
    parameters = (EffectParameter("c2", ""),)


class Shadowing(EvenSquare):
    name = "nonlinearity_cubic"


class DeclaredShadow(Effect):
    name = "nonlinearity_cubic"
    shadows = True
    parameters = (EffectParameter("c3", "1"),)

    def columns(self, inputs: EffectInputs, shape: Mapping[str, float]) -> dict[str, np.ndarray]:
        return {"c3": inputs.alpha_dps2**3 / inputs.range_dps2**2}


class Unbounded(SettlingBias):
    name = "unbounded"
    shape_parameters = (EffectParameter("time_constant_s", "s"),)


class Raising(EvenSquare):
    """A plugin with a bug in its model."""

    name = "raising"

    def columns(self, inputs: EffectInputs, shape: Mapping[str, float]) -> dict[str, np.ndarray]:
        return {"c2": inputs.alpha_dps2 * np.ones((2, 2))}  # shapes do not broadcast


class NotAnEffect:
    """Has the methods and declarations but does not derive from ``Effect``."""

    name = "not_an_effect"
    parameters = (EffectParameter("c", "1"),)
    enters = "voltage"

    def columns(self) -> None: ...
    def forward(self) -> None: ...
    def testable(self) -> None: ...
    def signature(self) -> None: ...


Install = Callable[[str, dict[str, str]], None]


@pytest.fixture
def install(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Install]:
    """Install a distribution declaring ``aatest.effects`` entry points (name → target)."""
    site = tmp_path / "site"
    site.mkdir()
    monkeypatch.syspath_prepend(str(site))
    fx.refresh()

    def _install(dist: str, points: dict[str, str]) -> None:
        info = site / f"{dist.replace('-', '_')}-1.0.dist-info"
        info.mkdir()
        (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: 1.0\n")
        (info / "entry_points.txt").write_text(
            "[aatest.effects]\n" + "".join(f"{k} = {v}\n" for k, v in points.items()))
        fx.refresh()

    yield _install
    monkeypatch.undo()
    fx.refresh()


def _here(cls: type) -> str:
    return f"{__name__}:{cls.__name__}"


def test_valid_plugins_join_the_vocabulary(install: Install) -> None:
    install("lab-effects", {"settling_bias": _here(SettlingBias), "even_square": _here(EvenSquare)})
    names = [c.effect for c in vocabulary()]
    assert names[:len(CANDIDATES)] == [c.effect for c in CANDIDATES]
    assert names[len(CANDIDATES):] == ["even_square", "settling_bias"]
    settling = next(c for c in vocabulary() if c.effect == "settling_bias")
    assert (settling.shape_params, settling.distribution) == (1, "lab-effects")


@pytest.mark.parametrize(("name", "cls", "message"), [
    ("no_unit", NoUnit, "parameter 'c2' states no unit"),
    ("nonlinearity_cubic", Shadowing, "shadows the built-in effect of that name"),
    ("unbounded", Unbounded, "shape parameter 'time_constant_s' needs bounds"),
    ("not_an_effect", NotAnEffect, "is not a subclass of aatest.effects.Effect"),
    ("other_name", EvenSquare, "calls itself 'even_square'"),
])
def test_broken_plugins_are_refused_naming_the_distribution(
        install: Install, name: str, cls: type, message: str) -> None:
    install("acme-broken", {name: _here(cls)})
    with pytest.raises(PluginError, match=message) as info:
        fx.installed_effects()
    assert "'acme-broken'" in str(info.value)
    if cls is not NotAnEffect:  # aatest.effects checks declarations, the class is checked on use
        listing = CliRunner().invoke(app, ["plugins"]).output
        head = message.split("'", maxsplit=1)[0]
        assert name in listing and "BROKEN" in listing and head in listing


def test_a_broken_plugin_stops_diagnose_with_exit_2(install: Install, tmp_path: Path) -> None:
    install("acme-broken", {"no_unit": _here(NoUnit)})
    result = CliRunner().invoke(app, ["diagnose", str(tmp_path / "anything")])
    assert result.exit_code == EXIT_BAD_INPUT, result.output


def test_one_name_from_two_distributions_is_refused(install: Install) -> None:
    install("lab-a", {"even_square": _here(EvenSquare)})
    install("lab-b", {"even_square": _here(EvenSquare)})
    with pytest.raises(PluginError, match=r"declared by several distributions \(lab-a, lab-b\)"):
        fx.installed_effects()


def test_declared_shadow_replaces_the_builtin(install: Install) -> None:
    install("lab-cubic", {"nonlinearity_cubic": _here(DeclaredShadow)})
    cubic = [c for c in vocabulary() if c.effect == "nonlinearity_cubic"]
    assert [c.distribution for c in cubic] == ["lab-cubic"]
    # --model-out writes it as the plugin's, not into the built-in field
    finding = {"effect": "nonlinearity_cubic", "parameters": {"c3": 0.03}, "channel": "v_sz"}
    rig = extended_model([{"channel": "v_sz", "axis": "I"}], [finding], 100.0, 25.0)
    sensor = rig.sensor("v_sz")
    assert sensor.nonlinearity_cubic is None
    assert [(p.effect, p.distribution, p.parameters) for p in sensor.plugin_effects or []] == [
        ("nonlinearity_cubic", "lab-cubic", {"c3": 0.03})]


def _inputs(n: int = 4001) -> SensorInputs:
    t = np.arange(n) / 2000.0
    alpha = np.zeros((3, n))
    alpha[2] = 300.0 * np.sin(2 * np.pi * 1.5 * t)
    return SensorInputs(alpha, np.zeros((3, n)), np.full(n, 25.0), np.eye(3), 1 / 2000.0, t - 0.2)


def test_twin_applies_the_forward_models(install: Install, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.syspath_prepend(str(EXAMPLE_SRC))
    install("aatest-vendor-example", {
        "asymmetric_scale": "aatest_vendor_example.effects:AsymmetricScale",
        "settling_bias": _here(SettlingBias)})
    plain = m.SensorModel()
    effects = [m.PluginEffect(effect="asymmetric_scale", parameters={"asymmetry": 0.04}),
               m.PluginEffect(effect="settling_bias",
                              parameters={"amplitude_v": 0.01, "time_constant_s": 0.5})]
    inp = _inputs()
    diff = (output_volts(plain.model_copy(update={"plugin_effects": effects}), inp, 25.0)
            - output_volts(plain, inp, 25.0))
    alpha, t = inp.alpha_top_dps2[2], inp.time_s
    assert t is not None
    k = plain.scale_v_per_dps2
    # K₊ = K(1 + a/2) for α > 0, K₋ = K(1 − a/2) for α < 0; plus A·exp(−t/τ) from t = 0
    expected = (k * alpha * np.where(alpha > 0, 0.02, -0.02)
                + 0.01 * np.exp(-np.clip(t, 0, None) / 0.5))
    np.testing.assert_allclose(diff, expected, atol=1e-12)


def test_a_failing_plugin_model_is_the_plugins_error(install: Install) -> None:
    install("acme-buggy", {"raising": _here(Raising)})
    sensor = m.SensorModel(plugin_effects=[m.PluginEffect(effect="raising",
                                                          parameters={"c2": 0.1})])
    with pytest.raises(PluginError, match=r"'raising' from distribution 'acme-buggy' failed in "
                                          r"forward\(\): ValueError") as info:
        output_volts(sensor, _inputs(), 25.0)
    assert info.value.exit_code == EXIT_BAD_INPUT
    inputs = EffectInputs(np.ones(8), np.ones(8), np.zeros(8), np.arange(8.0), 1e-3, 500.0)
    with pytest.raises(PluginError, match="'raising' from distribution 'acme-buggy' failed in "
                                          "columns"):
        fx.design_columns([fx.spec_token("raising")], inputs, {})


def test_model_parameters_are_checked_against_the_plugin(install: Install) -> None:
    install("lab-effects", {"settling_bias": _here(SettlingBias)})
    with pytest.raises(ValueError, match="takes parameters amplitude_v, time_constant_s"):
        m.PluginEffect(effect="settling_bias", parameters={"amplitude_v": 0.01})
    with pytest.raises(ValueError, match=r"time_constant_s = 5 s is outside \[0.05, 2\]"):
        m.PluginEffect(effect="settling_bias",
                       parameters={"amplitude_v": 0.01, "time_constant_s": 5.0})


def test_missing_plugin_in_a_rig_model_is_exit_2(install: Install, tmp_path: Path) -> None:
    install("lab-effects", {"settling_bias": _here(SettlingBias)})
    sensor = m.SensorModel(plugin_effects=[m.PluginEffect(
        effect="settling_bias", distribution="lab-effects",
        parameters={"amplitude_v": 0.01, "time_constant_s": 0.5})])
    model = tmp_path / "model.yaml"
    m.dump_rig_model(m.RigModel(sensors=[sensor]), model)
    assert m.load_rig_model(model).sensors[0].plugin_effects == sensor.plugin_effects
    fx.refresh()
    (next((tmp_path / "site").glob("lab_effects-*.dist-info")) / "entry_points.txt").write_text("")
    fx.refresh()
    rig = tmp_path / "rig.yaml"
    rig.write_text(f"turntable: {{plugin: sim, model: {model}}}\ndaq: {{plugin: sim, model: "
                   f"{model}}}\nchamber: {{plugin: none}}\n")
    procedure = HERE.parents[1] / "src" / "aatest" / "procedures" / "scale-factor.yaml"
    result = CliRunner().invoke(app, ["validate", str(procedure), "--rig", str(rig)])
    assert result.exit_code == EXIT_BAD_INPUT, result.output
    assert "effect 'settling_bias' is not installed" in result.output
    assert "install the distribution 'lab-effects'" in result.output


@pytest.mark.slow
def test_diagnose_fits_a_shape_parameter(install: Install, tmp_path: Path) -> None:
    """A voltage effect with a searched time constant, generated by the twin, is recovered."""
    from aatest.diagnose.scenarios import clean_rig, diagnostic_plan
    from aatest.recording.data.exporter import export_csv
    from aatest.twin.api import simulate_dataset

    install("lab-effects", {"settling_bias": _here(SettlingBias)})
    truth = {"amplitude_v": 0.02, "time_constant_s": 0.4}
    rig = clean_rig(5)
    sensor = rig.sensors[0].model_copy(update={"plugin_effects": [
        m.PluginEffect(effect="settling_bias", distribution="lab-effects", parameters=truth)]})
    data = tmp_path / "import"
    export_csv(simulate_dataset(rig.model_copy(update={"sensors": [sensor]}),
                                diagnostic_plan(2**13), 5, procedure="settling"), data)
    out = tmp_path / "d.json"
    result = CliRunner().invoke(app, ["diagnose", str(data), "--json", str(out),
                                      "--model-out", str(tmp_path / "model.yaml")])
    assert "Traceback" not in result.output
    doc = json.loads(out.read_text())
    assert [f["effect"] for f in doc["findings"]] == ["settling_bias"], doc["findings"]
    found = doc["findings"][0]["parameters"]
    for key, value in truth.items():
        assert found[key] == pytest.approx(value, rel=0.25), key
    written = m.load_rig_model(tmp_path / "model.yaml").sensors[0].plugin_effects
    assert written is not None and written[0].parameters == pytest.approx(found)
