"""Analyses run in the order their ``requires`` give, whatever order a procedure lists them in;
plugin classes are checked when loaded; cycles and unknown requirements are plugin errors."""

from __future__ import annotations

from typing import Any

import pytest
from pydantic import BaseModel, ConfigDict
from synthetic_rig import SynthRig, make_dataset, sine_step, static_step

from aatest.engine import registry
from aatest.engine.analysis import plugins
from aatest.engine.analysis.passes import order, run_analyses
from aatest.engine.errors import PluginError
from aatest.engine.interfaces import AnalysisOutput, NoOptions
from aatest.results.base import ResultModel


@pytest.fixture(scope="module")
def mixed() -> Any:
    """Seven sine steps (one near 1 Hz) and four static positions on the synthetic rig."""
    steps = [sine_step(f"s{c}", c, 100.0, samples=8192) for c in (4, 8, 16, 24, 32, 41, 60)]
    steps += [static_step(f"t{i}", 0, o, samples=4096) for i, o in enumerate((0, 180, 0, 180))]
    return make_dataset(steps, SynthRig())


def _dump(names: list[str], data: Any) -> dict[str, Any]:
    done = run_analyses(data, names)
    assert done.errors == {}
    return {k: v.model_dump(mode="json") for k, v in done.values.items()}


def test_requirements_come_first() -> None:
    assert [p.name for p in order(["transfer_function"])] == ["sync", "frf", "transfer_function"]
    assert [p.name for p in order(["noise", "bias"])] == ["sync", "bias", "scale_factor", "noise"]


def test_listing_order_does_not_change_results(mixed: Any) -> None:
    forward = _dump(["frf", "transfer_function"], mixed)
    backward = _dump(["transfer_function", "frf"], mixed)
    assert set(forward) == {"sync", "frf", "transfer_function"}
    assert forward == backward


def test_noise_uses_the_calibrated_scale_only_through_its_requirement(mixed: Any) -> None:
    a = _dump(["noise", "scale_factor"], mixed)
    b = _dump(["scale_factor", "noise"], mixed)
    c = _dump(["noise"], mixed)  # pulls scale_factor in
    assert a == b == c
    calibrated = a["scale_factor"]["v_sz"]["scale_v_per_dps2"]
    assert a["noise"]["v_sz"]["scale_v_per_dps2_used"] == calibrated
    # bias does not require the scale factor: the same with or without it in the pass
    assert _dump(["bias"], mixed)["bias"] == _dump(["scale_factor", "bias"], mixed)["bias"]


class _Result(ResultModel):
    value: int = 0


def _fake(key: str, requires: tuple[str, ...], attrs: dict[str, Any] | None = None) -> type:
    def run(self: Any, data: Any, context: Any) -> AnalysisOutput[_Result]:
        return AnalysisOutput(_Result(value=len(context.upstream)))

    body = {"key": key, "requires": requires, "Options": NoOptions, "Result": _Result,
            "applies_to": lambda self, data: True, "run": run}
    return type(f"Fake_{key}", (), body | (attrs or {}))


@pytest.fixture
def fake_plugins(monkeypatch: pytest.MonkeyPatch) -> dict[str, type]:
    """Analysis plugins from a fake distribution, found instead of the installed ones."""
    classes: dict[str, type] = {}

    def load(kind: str, name: str) -> registry.PluginInfo:
        if name not in classes:
            raise PluginError(f"no {kind} plugin named {name!r}")
        return registry.PluginInfo(kind, name, classes[name], "fake-dist", "1.0")

    monkeypatch.setattr(registry, "load", load)
    return classes


def test_a_cycle_is_a_plugin_error_naming_the_plugins(fake_plugins: dict[str, type]) -> None:
    fake_plugins |= {"a": _fake("a", ("b",)), "b": _fake("b", ("c",)), "c": _fake("c", ("a",))}
    with pytest.raises(PluginError, match=r"cycle: analysis plugin '[abc]' from distribution "
                                          r"'fake-dist' → .*'fake-dist'"):
        order(["a"])


def test_an_unknown_requirement_names_the_requirer(fake_plugins: dict[str, type]) -> None:
    fake_plugins["a"] = _fake("a", ("zzz",))
    with pytest.raises(PluginError, match="analysis plugin 'a' from distribution 'fake-dist' "
                                          "requires 'zzz'"):
        order(["a"])


def test_upstream_holds_only_the_requirements(fake_plugins: dict[str, type]) -> None:
    fake_plugins |= {"a": _fake("a", ()), "b": _fake("b", ()), "c": _fake("c", ("a",))}
    done = run_analyses(make_dataset([], SynthRig()), ["b", "c"])
    assert {k: v.value for k, v in done.values.items()} == {"a": 0, "b": 0, "c": 1}


class _Loose(BaseModel):
    threshold: float = 1.0


class _Required(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    threshold: float


@pytest.mark.parametrize("attrs, match", [
    ({"key": ""}, "non-empty string 'key'"),
    ({"requires": ["sync"]}, "'requires' must be a tuple"),
    ({"Options": dict}, "pydantic 'Options' model"),
    ({"Options": _Loose}, "frozen with extra='forbid'"),
    ({"Options": _Required}, "every option needs a default"),
    ({"Result": None}, "'Result' type"),
], ids=["key", "requires", "options-not-model", "options-loose", "options-no-default", "result"])
def test_plugin_classes_are_checked_when_loaded(fake_plugins: dict[str, type],
                                                attrs: dict[str, Any], match: str) -> None:
    fake_plugins["bad"] = _fake("bad", (), attrs)
    with pytest.raises(PluginError, match=f"'bad' from distribution 'fake-dist'.*{match}"):
        plugins.load("bad")


def test_a_failed_requirement_fails_its_dependants_not_the_pass() -> None:
    from dataclasses import replace

    import numpy as np

    from aatest.engine.logs import SampledLog

    data = make_dataset([sine_step("s", 8, 100.0, samples=4096)], SynthRig())
    table = data.steps[0].table
    channels = dict(table.channels) | {"sync_pulse": np.zeros(len(table))}
    broken = replace(data.steps[0], table=SampledLog("table", 2000.0, table.time_s, channels))
    done = run_analyses(replace(data, steps=(broken,)), ["frf"])
    assert done.outputs == {}
    assert "sync edges missing" in done.errors["sync"]
    assert "the sync analysis failed" in done.errors["frf"]
