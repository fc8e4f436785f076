"""Loader: located problems, all at once; rig files; malformed YAML never escapes as a crash."""

from __future__ import annotations

import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from ruamel.yaml import YAML

import aatest
from aatest.engine.errors import EXIT_BAD_INPUT, ProcedureError
from aatest.engine.procedure.loader import (
    PluginSpec,
    load_procedure,
    load_rig,
    parse_procedure,
    rig_from_procedure,
)
from aatest.engine.procedure.planner import expand

SHIPPED = Path(aatest.__file__).parent / "procedures"
DATA = Path(__file__).parents[1] / "data" / "procedures"


def _problems(path: Path) -> list[str]:
    with pytest.raises(ProcedureError) as info:
        load_procedure(path)
    assert info.value.exit_code == EXIT_BAD_INPUT
    return [str(p) for p in info.value.problems]


def test_wrong_types_are_all_reported_with_positions() -> None:
    path = DATA / "broken-wrong-type.yaml"
    problems = _problems(path)
    assert problems == [
        f"{path}:3:12: sampling.rate_hz: Input should be a valid number (got 'fast'; expected "
        "a number in Hz, e.g. 1000)",
        f"{path}:5:44: steps.0.sine.accel_dps2: Input should be a valid number (got '400'; "
        "expected a number in °/s², e.g. 400)",
    ]


def test_unknown_keys_are_named() -> None:
    path = DATA / "broken-unknown-key.yaml"
    problems = _problems(path)
    assert problems == [
        f"{path}:8:7: steps.0.sine.amplitde_deg: unknown key; did you mean 'amplitude_deg'?",
        f"{path}:9:5: steps.1.spin: unknown key; did you mean 'sine'? A step is one of: static, "
        "sine, sine_sweep, constant_rate, coordinated_rates, multi_position, temperature_steps, "
        "repeat, misalignment, operator",
    ]


def test_step_needs_exactly_one_kind() -> None:
    text = "procedure: x\nsensor: {model: m}\nsteps:\n  - {}\n  - static: {}\n    sine: {}\n"
    with pytest.raises(ProcedureError) as info:
        parse_procedure(text, "p.yaml")
    messages = [str(p) for p in info.value.problems]
    assert messages[0].startswith("p.yaml:4:5: steps.0: Value error, a step needs exactly one")
    assert "steps.1.sine" in messages[1]  # the empty sine body is itself incomplete


def test_trailing_operator_prompt_is_an_error() -> None:
    with pytest.raises(ProcedureError, match="operator prompt with no step"):
        parse_procedure("procedure: x\nsensor: {model: m}\nsteps:\n  - operator: {prompt: hi}\n")


def test_syntax_error_and_missing_file_are_located() -> None:
    with pytest.raises(ProcedureError, match=r"^p.yaml:2:\d+: YAML syntax"):
        parse_procedure("procedure: x\n  sensor: [\n", "p.yaml")
    with pytest.raises(ProcedureError, match="cannot read file"):
        load_procedure(DATA / "no-such-file.yaml")


def test_recursive_alias_is_a_problem_not_a_crash() -> None:
    with pytest.raises(ProcedureError):
        parse_procedure("procedure: x\nsensor: &a {model: *a}\nsteps: &s [*s]\n")


@pytest.mark.parametrize("sine", ["{frequency_hz: 1.0e300, accel_dps2: 1}",
                                  "{cycles: 1" + "0" * 29 + ", amplitude_deg: 1.0e300}",
                                  "{frequency_hz: 1.0e-300, accel_dps2: 1.0e300, snap: none}"],
                         ids=["huge-f", "huge-cycles", "tiny-f"])
def test_absurd_numbers_never_crash_the_planner(sine: str) -> None:
    text = f"procedure: x\nsensor: {{model: m}}\nsteps:\n  - sine: {sine}\n"
    try:
        expand(parse_procedure(text, "p.yaml"))
    except ProcedureError as exc:
        assert str(exc).startswith("p.yaml:4:5: steps.0.sine: cannot expand")


def test_planning_problems_are_located_too() -> None:
    text = ("procedure: x\nsensor: {model: m}\nsteps:\n  - static: {}\n  - sine_sweep:\n"
            "      frequencies: {start_hz: 0.001, ratio: 1.0001, stop_hz: 10}\n"
            "      accelerations_dps2: [1]\n")
    expected = r"^p.yaml:5:5: steps.1.sine_sweep: the geometric grid"
    with pytest.raises(ProcedureError, match=expected):
        expand(parse_procedure(text, "p.yaml"))


def test_every_shipped_procedure_validates() -> None:
    names = sorted(p.stem for p in SHIPPED.glob("*.yaml"))
    assert names == ["long-static-drift", "pivoted-misalignment", "scale-factor",
                     "static-multi-position",
                     "stepped-sine-frequency-response", "study-transfer-function",
                     "temperature-steps"]
    for path in SHIPPED.glob("*.yaml"):
        proc = load_procedure(path)
        assert proc.procedure == path.stem and proc.source_file == str(path)


def test_rig_file_flattens_plugin_options(tmp_path: Path) -> None:
    rig_file = tmp_path / "rig.yaml"
    rig_file.write_text("turntable: {plugin: modbus, host: 127.0.0.1, port: 5020}\n"
                        "daq: {plugin: can, interface: virtual, channel: aatest}\n")
    rig = load_rig(rig_file)
    assert rig.turntable == PluginSpec(plugin="modbus", options={"host": "127.0.0.1", "port": 5020})
    assert rig.daq.options == {"interface": "virtual", "channel": "aatest"}
    assert rig.chamber == PluginSpec(plugin="none")


def test_rig_file_errors_are_located(tmp_path: Path) -> None:
    rig_file = tmp_path / "rig.yaml"
    rig_file.write_text("turntable: {plugin: sim}\nlaser: {plugin: x}\ndaq: {host: h}\n")
    with pytest.raises(ProcedureError) as info:
        load_rig(rig_file)
    messages = sorted(str(p) for p in info.value.problems)
    assert any(m.startswith(f"{rig_file}:2:1: laser: unknown key") for m in messages)
    assert any(m.startswith(f"{rig_file}:3:1: daq.") for m in messages)


def test_rig_file_plugin_options_are_checked_and_located(tmp_path: Path) -> None:
    """A plugin's bad option is refused as the rig file loads, at its own line and column,
    in either form (flat beside ``plugin:`` or under ``options:``), with the unknown plugin
    name at its ``plugin:`` — before, these errors named neither the file nor the line."""
    rig_file = tmp_path / "rig.yaml"
    rig_file.write_text("turntable: {plugin: sim, modle: twin.yaml}\n"
                        "daq:\n  plugin: can\n  options:\n    bitrate: fast\n"
                        "chamber:\n  plugin: expec\n")
    with pytest.raises(ProcedureError) as info:
        load_rig(rig_file)
    assert info.value.exit_code == EXIT_BAD_INPUT
    messages = [str(p) for p in info.value.problems]
    assert messages[0] == (f"{rig_file}:1:26: turntable.modle: turntable plugin 'sim' "
                           "(aatest): unknown option; did you mean 'model'?")
    assert messages[1].startswith(f"{rig_file}:5:5: daq.options.bitrate: daq plugin 'can' "
                                  "(aatest): Input should be a valid integer")
    assert messages[2].startswith(f"{rig_file}:7:3: chamber.plugin: no chamber plugin named "
                                  "'expec'")
    assert len(messages) == 3


def test_rig_from_procedure_uses_the_named_plugins() -> None:
    rig = rig_from_procedure(load_procedure(SHIPPED / "temperature-steps.yaml"))
    assert (rig.turntable.plugin, rig.daq.plugin, rig.chamber.plugin) == ("sim", "sim", "sim")


# --- fuzzing: whatever the text, only ProcedureError ----------------------------------------

_VALID = (SHIPPED / "stepped-sine-frequency-response.yaml").read_text(encoding="utf-8")
_yaml_scalars = st.one_of(st.none(), st.booleans(), st.integers(), st.text(max_size=8),
                          st.floats(allow_nan=True, allow_infinity=True))
_keys = st.sampled_from(["procedure", "sensor", "steps", "sine", "sine_sweep", "repeat",
                         "frequencies", "model", "axis", "count", "operator", "prompt",
                         "cycles", "samples", "x"])
_trees = st.recursive(_yaml_scalars, lambda children: st.one_of(
    st.lists(children, max_size=4), st.dictionaries(_keys, children, max_size=4)), max_leaves=20)


def _dump(tree: object) -> str:
    import io

    out = io.StringIO()
    YAML(typ="safe").dump(tree, out)
    return out.getvalue()


def _loads_or_procedure_error(text: str) -> None:
    """Loading (and planning what loads) fails only with located problems."""
    try:
        expand(parse_procedure(text, "fuzz.yaml"))
    except ProcedureError as exc:
        assert exc.problems and all(p.file == "fuzz.yaml" and p.line >= 1 for p in exc.problems)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.text(max_size=200))
def test_arbitrary_text_only_raises_procedure_error(text: str) -> None:
    _loads_or_procedure_error(text)


@settings(max_examples=150, deadline=None)
@given(st.integers(0, len(_VALID) - 1), st.integers(0, 40), st.text(max_size=6))
def test_mutated_procedure_only_raises_procedure_error(at: int, cut: int, insert: str) -> None:
    _loads_or_procedure_error(_VALID[:at] + insert + _VALID[at + cut:])


@settings(max_examples=60, deadline=None)
@given(st.integers(0, len(_VALID) - 1), st.binary(max_size=8))
def test_corrupted_files_only_raise_procedure_error(at: int, junk: bytes) -> None:
    raw = _VALID.encode()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "fuzz.yaml"
        path.write_bytes(raw[:at] + junk + raw[at:])
        try:
            expand(load_procedure(path))
        except ProcedureError as exc:
            assert all(p.file == str(path) for p in exc.problems)


@settings(max_examples=150, deadline=None)
@given(st.dictionaries(_keys, _trees, max_size=6))
def test_random_trees_only_raise_procedure_error(tree: dict) -> None:
    _loads_or_procedure_error(_dump(tree))
