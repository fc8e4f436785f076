"""Envelope check: each violated limit is reported with the step, the limit and the value."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from aatest.cli import app
from aatest.engine.errors import EXIT_BAD_INPUT, EnvelopeError, ProcedureError
from aatest.engine.interfaces import AxisLimits, SensorDatasheet, TableEnvelope
from aatest.engine.procedure.envelope import check_envelope, step_violations
from aatest.engine.procedure.loader import load_procedure, parse_procedure
from aatest.engine.procedure.planner import default_datasheet, expand, expand_traced
from aatest.engine.steps import PlannedStep
from aatest.positioned_yaml import locate

DATA = Path(__file__).parents[1] / "data" / "procedures"
SHEET = SensorDatasheet(model="sr207")
ENV = TableEnvelope()


def _sine(freq_hz: float, amp_deg: float, axis: str = "inner", **kw: object) -> PlannedStep:
    accel = amp_deg * (2 * 3.141592653589793 * freq_hz) ** 2
    return PlannedStep(id="s001-x", kind="sine", axis=axis, frequency_hz=freq_hz,
                       amplitude_deg=amp_deg, accel_dps2=accel, samples=8192, **kw)


def _limits(step: PlannedStep, env: TableEnvelope = ENV) -> set[str]:
    return {v.limit for v in step_violations(step, env, SHEET)}


def test_2000dps2_on_the_inner_axis_is_rejected_with_its_position() -> None:
    path = DATA / "broken-inner-2000dps2.yaml"
    plan = expand(load_procedure(path))
    with pytest.raises(EnvelopeError) as info:
        check_envelope(plan, ENV, SHEET, str(path))
    assert info.value.exit_code == EXIT_BAD_INPUT
    messages = [str(p) for p in info.value.problems]
    table = next(m for m in messages if "[inner.accel_dps2]" in m)
    assert table.startswith(f"{path}:7:5: s002-sine-inner-1.9531Hz-2000dps2: peak table "
                            "acceleration 2000 °/s² exceeds inner.accel_dps2 1000 °/s²")
    assert "terminal frequency" in table
    assert any("[sensor.test_ceiling_dps2]" in m for m in messages)


def test_outer_axis_has_its_own_lower_limits() -> None:
    step = _sine(1.0, 250 / (2 * 3.141592653589793) ** 2, axis="outer")  # 250 °/s² on outer
    assert _limits(step) == {"outer.accel_dps2"}
    assert _limits(_sine(1.0, 2.5, axis="outer")) == set()  # 98.7 °/s² fits


@pytest.mark.parametrize(("step", "limit"), [
    (_sine(0.25, 900.0), "inner.rate_dps"),         # A·ω = 1414 °/s > 1200 °/s
    (_sine(10.5, 0.1), "max_frequency_hz"),
    (_sine(1.0, 0.015), "sensor.floor_dps2"),       # 0.59 °/s² below the 0.8 °/s² floor
    (_sine(1.0, 12.0), "sensor.test_ceiling_dps2"),  # 474 °/s² above 458.4 °/s²
    (_sine(1.0, 5.0, sample_rate_hz=5000.0), "max_log_rate_hz"),
], ids=["rate", "terminal", "floor", "ceiling", "log-rate"])
def test_each_limit_is_named(step: PlannedStep, limit: str) -> None:
    assert limit in _limits(step)


def test_peak_rate_is_amplitude_times_omega() -> None:
    # 0.1 Hz, 900°: rate 565.5 °/s would fit the inner 1200 °/s but not the outer 500 °/s
    step = _sine(0.1, 900.0, axis="outer")
    (rate,) = [v for v in step_violations(step, ENV, SHEET) if v.limit == "outer.rate_dps"]
    assert rate.value == pytest.approx(900 * 2 * 3.141592653589793 * 0.1, rel=1e-12)
    assert "outer.rate_dps" not in _limits(_sine(0.1, 700.0, axis="outer"))  # 439.8 °/s


def test_record_longer_than_the_log_capacity() -> None:
    step = PlannedStep(id="s1", kind="static", samples=230_001)
    assert _limits(step) == {"log_capacity_samples"}
    assert _limits(PlannedStep(id="s1", kind="static", samples=230_000)) == set()


def test_value_exactly_at_the_limit_passes() -> None:
    amp = 1000 / (2 * 3.141592653589793 * 2.0) ** 2
    assert "inner.accel_dps2" not in _limits(_sine(2.0, amp))


def test_constant_and_coordinated_rates_against_rate_limits() -> None:
    fast = PlannedStep(id="s1", kind="constant_rate", axis="inner", rate_dps=-1300.0, samples=10)
    assert _limits(fast) == {"inner.rate_dps"}
    coord = PlannedStep(id="s1", kind="constant_rate", axis="both", rate_dps=1080.0,
                        outer_rate_dps=600.0, accel_dps2=11309.7, samples=10)
    assert _limits(coord) == {"outer.rate_dps", "sensor.test_ceiling_dps2"}


def test_travel_limits_of_an_axis_with_stops() -> None:
    env = TableEnvelope(outer=AxisLimits(rate_dps=500, accel_dps2=200, continuous=False,
                                         min_deg=-90, max_deg=90))
    assert _limits(PlannedStep(id="s", kind="static", outer_deg=180.0, samples=1), env) == {
        "outer.max_deg"}
    assert _limits(_sine(1.0, 2.0, axis="outer", outer_deg=-89.0), env) == {"outer.min_deg"}


def test_sweep_without_skip_groups_the_points_of_an_element_into_one_problem() -> None:
    proc = parse_procedure(
        "procedure: s\nsensor: {model: sr207}\nsteps:\n  - sine_sweep:\n"
        "      frequencies: {include: [1, 8, 9]}\n      amplitudes_deg: [0.2]\n")
    with pytest.raises(EnvelopeError) as info:
        check_envelope(expand(proc), ENV, SHEET, None, locate=lambda p: locate(proc.source_tree, p))
    (problem,) = info.value.problems
    assert (problem.line, problem.column) == (6, 24)  # the 0.2 itself
    assert problem.field == "steps.0.sine_sweep.amplitudes_deg.0"
    # worst point: A·(2πf)² = 0.2° · (2π · 9.0027 Hz)² = 639.93 °/s² (ceiling 0.8 · 573 °/s²)
    assert problem.message == (
        "2 steps from this entry leave the envelope (s002-sine-inner-7.9956Hz-0.2deg … "
        "s003-sine-inner-9.0027Hz-0.2deg): 2 × [sensor.test_ceiling_dps2], worst: peak "
        "acceleration 639.932 °/s² exceeds sensor.test_ceiling_dps2 458.366 °/s² "
        "(80% of the sr207 range)")


def test_skip_is_decided_against_the_given_envelope() -> None:
    text = ("procedure: s\nsensor: {model: sr207}\nsteps:\n  - static: {}\n  - sine_sweep:\n"
            "      frequencies: {include: [1, 3]}\n      amplitudes_deg: [0.5]\n"
            "      skip_outside_envelope: true\n")
    small = SensorDatasheet(model="small", range_dps2=100.0)  # ceiling 80 °/s²
    expansion = expand_traced(parse_procedure(text), datasheet=small)
    assert [s.kind for s in expansion.plan.steps] == ["static", "sine"]  # 3 Hz: 178 °/s²
    (skipped,) = expansion.skipped
    assert skipped.limits == ("sensor.test_ceiling_dps2",)
    assert len(expand(parse_procedure(text)).steps) == 3


def test_a_group_with_every_point_outside_is_an_error_at_its_element() -> None:
    text = ("procedure: s\nsensor: {model: sr207}\nsteps:\n  - sine_sweep:\n"
            "      frequencies: {include: [1, 2]}\n      accelerations_dps2: [100, 2000]\n"
            "      skip_outside_envelope: true\n")
    with pytest.raises(ProcedureError) as info:
        expand(parse_procedure(text))
    (problem,) = info.value.problems
    assert (problem.line, problem.column, problem.field) == (
        6, 33, "steps.0.sine_sweep.accelerations_dps2.1")
    assert problem.message.startswith("every one of the 2 points of this group lies outside "
                                      "the envelope (peak table acceleration 2000 °/s² exceeds "
                                      "inner.accel_dps2 1000 °/s²")


STEPPED_SINE = Path(__file__).parents[2] / "src" / "aatest" / "procedures" / \
    "stepped-sine-frequency-response.yaml"


def _stepped_sine_with_2000(tmp_path: Path, skip: bool) -> Path:
    """The measured case of issue 14: the 400 °/s² group changed to 2000 °/s²."""
    text = STEPPED_SINE.read_text().replace("accelerations_dps2: [1, 10, 100, 400]",
                                            "accelerations_dps2: [1, 10, 100, 2000]")
    assert "2000]" in text
    if not skip:
        text = text.replace("skip_outside_envelope: true", "skip_outside_envelope: false")
    path = tmp_path / "stepped-sine-2000.yaml"
    path.write_text(text)
    return path


def test_measured_case_with_skip_names_the_group_that_is_entirely_outside(
        tmp_path: Path) -> None:
    path = _stepped_sine_with_2000(tmp_path, skip=True)
    result = CliRunner().invoke(app, ["validate", str(path)])
    assert result.exit_code == EXIT_BAD_INPUT
    assert result.output.startswith(
        f"error: {path}:28:40: steps.0.sine_sweep.accelerations_dps2.3: every one of the 28 "
        "points of this group lies outside the envelope"), result.output


def test_measured_case_without_skip_gives_one_problem_per_offending_element(
        tmp_path: Path) -> None:
    path = _stepped_sine_with_2000(tmp_path, skip=False)
    result = CliRunner().invoke(app, ["validate", str(path)])
    assert result.exit_code == EXIT_BAD_INPUT
    lines = result.output.splitlines()
    assert [line.split(": ")[0:2] for line in lines] == [
        [f"{path}:27:24", "steps.0.sine_sweep.amplitudes_deg.0"],
        [f"{path}:28:40", "steps.0.sine_sweep.accelerations_dps2.3"]]
    assert "4 steps from this entry" in lines[0] and "4 × [sensor.test_ceiling_dps2]" in lines[0]
    assert "28 steps from this entry" in lines[1] and "28 × [inner.accel_dps2]" in lines[1]
    assert "28 × [sensor.test_ceiling_dps2]" in lines[1]


def test_validate_and_plan_list_the_skipped_points_with_their_limit() -> None:
    result = CliRunner().invoke(app, ["validate", str(STEPPED_SINE)])
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    assert lines[0].endswith("OK — 136 steps, lab duration 9592.9 s")
    assert lines[1] == "skipped 4 point(s) outside the envelope (skip_outside_envelope: true):"
    assert lines[6] == "analyses and the steps each will use:"
    assert all(line.startswith("  sine-inner-") and line.endswith("[sensor.test_ceiling_dps2]")
               for line in lines[2:6])
    result = CliRunner().invoke(app, ["plan", "--json", str(STEPPED_SINE)])
    skipped = json.loads(result.output)["skipped"]
    assert [s["limits"] for s in skipped] == [["sensor.test_ceiling_dps2"]] * 4
    assert len(skipped) + len(json.loads(result.output)["steps"]) == 28 * 5


def test_every_shipped_procedure_fits_with_the_plugin_datasheets() -> None:
    import aatest

    env = ENV.model_copy(update={"streaming_daq": True})  # they all run on the sim DAQ
    for path in sorted((Path(aatest.__file__).parent / "procedures").glob("*.yaml")):
        proc = load_procedure(path)
        sheet = default_datasheet(proc.sensor.model)
        assert sheet.model == proc.sensor.model
        check_envelope(expand(proc, envelope=env, datasheet=sheet), env, sheet, str(path))


def test_unknown_sensor_model_falls_back_to_generic_values() -> None:
    assert default_datasheet("no-such-sensor") == SensorDatasheet(model="no-such-sensor")


SINGLE_AXIS = TableEnvelope(axes=("inner",))


@pytest.mark.parametrize(("step", "limits"), [
    (_sine(1.0, 2.5, axis="outer"), {"outer.present"}),  # 98.7 °/s²: within any outer limit
    (PlannedStep(id="s", kind="static", outer_deg=90.0, samples=1), {"outer.present"}),
    (PlannedStep(id="s", kind="constant_rate", axis="both", rate_dps=100.0,
                 outer_rate_dps=10.0, accel_dps2=17.5, samples=10), {"outer.present"}),
    (_sine(1.0, 2.5), set()),
    (PlannedStep(id="s", kind="static", inner_deg=90.0, samples=1), set()),
], ids=["outer-sine", "outer-position", "coordinated", "inner-sine", "inner-position"])
def test_an_absent_axis_is_refused_whatever_its_limits(step: PlannedStep,
                                                       limits: set[str]) -> None:
    assert _limits(step, SINGLE_AXIS) == limits
    if limits:
        [violation] = step_violations(step, SINGLE_AXIS, SHEET)
        assert not violation.skippable and "(declared axes: inner)" in violation.message


def test_axes_must_include_inner_once() -> None:
    for axes in ((), ("outer",), ("inner", "inner")):
        with pytest.raises(ValueError, match="axes must name 'inner'"):
            TableEnvelope(axes=axes)  # type: ignore[arg-type]


@pytest.mark.parametrize("set_point_c, refused", [
    (-40.0, False), (85.0, False), (-41.0, True), (90.0, True)])
def test_a_set_point_outside_the_sensors_operating_temperatures_is_refused(
        set_point_c: float, refused: bool) -> None:
    """The chamber is commanded only where the sensor may go: the sr207's −40 to 85 °C
    (docs/method.md §1.3), edges included; not skippable, as a motion point is."""
    step = PlannedStep(id="s001-chamber", kind="chamber", temperature_c=set_point_c)
    found = step_violations(step, ENV, SHEET)
    assert [v.limit for v in found] == (["sensor.operating_temperature_c"] if refused else [])
    assert all(not v.skippable and "operating temperature range -40 to 85 °C" in v.message
               for v in found)


def test_validate_refuses_a_temperature_campaign_beyond_the_sensor(tmp_path: Path) -> None:
    path = tmp_path / "hot.yaml"
    path.write_text("""\
procedure: hot
sensor: {model: sr207, serial: "H1"}
rig: {turntable: sim, daq: sim, chamber: sim}
sampling: {rate_hz: 2000, samples: 4096, settle_s: 0.5}
steps:
  - temperature_steps: {setpoints_c: [22, 60, 95], soak_s: 10}
analysis: [sync, temperature]
""", encoding="utf-8")
    done = CliRunner().invoke(app, ["validate", str(path)])
    assert done.exit_code == EXIT_BAD_INPUT, done.output
    assert f"{path}:6:5: s005-chamber-95C: " in done.output  # one step: named
    assert "chamber set-point 95 °C is above the sr207's operating temperature range" \
           in done.output
