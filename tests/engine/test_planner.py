"""Planner: generators expand into the published steps with physically right numbers."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

import aatest
from aatest.engine.procedure.loader import load_procedure, parse_procedure
from aatest.engine.procedure.models import SweepFrequencies
from aatest.engine.procedure.planner import (
    expand,
    expand_traced,
    snap_frequency,
    sweep_points,
    trace_of,
)

SHIPPED = Path(aatest.__file__).parent / "procedures"
DATA = Path(__file__).parents[1] / "data" / "procedures"

#: docs/method.md §4.4, the published 28-point matrix (Hz)
PUBLISHED_HZ = np.array([
    0.396728516, 0.473022461, 0.579833984, 0.686645508, 0.823974609, 0.991821289, 1.007080078,
    1.190185547, 1.434326172, 1.708984375, 1.998901367, 2.059936523, 2.487182617, 2.975463867,
    3.005981445, 3.570556641, 3.997802734, 4.272460938, 5.004882813, 5.142211914, 5.996704102,
    6.164550781, 7.003784180, 7.400512695, 7.995605469, 8.880615234, 9.002685547, 9.994506836])


def _sweep_steps(group: str) -> list:
    plan = expand(load_procedure(SHIPPED / "stepped-sine-frequency-response.yaml"))
    return [s for s in plan.steps if s.group == group]


@pytest.mark.parametrize("accel_dps2", [1, 10, 100, 400], ids=lambda a: f"{a}dps2")
def test_stepped_sine_reproduces_the_28_published_frequencies(accel_dps2: int) -> None:
    steps = _sweep_steps(f"accel-{accel_dps2}")
    freqs = np.array([s.frequency_hz for s in steps])
    # the published values are printed to 1e-9 Hz: compare to half a unit of the last digit
    assert_allclose(freqs, PUBLISHED_HZ, rtol=0, atol=0.5e-9 + 1e-12)
    assert [s.cycles for s in steps] == [round(f * 131072 / 2000) for f in freqs]


@pytest.mark.parametrize("accel_dps2", [1, 10, 100, 400], ids=lambda a: f"{a}dps2")
def test_constant_acceleration_amplitudes(accel_dps2: int) -> None:
    steps = _sweep_steps(f"accel-{accel_dps2}")
    amps = np.array([s.amplitude_deg for s in steps])
    expected = accel_dps2 / (2 * np.pi * PUBLISHED_HZ) ** 2
    assert_allclose(amps, expected, rtol=1e-8, atol=1e-6)
    assert_allclose([s.accel_dps2 for s in steps], accel_dps2, rtol=1e-12)


def test_first_point_at_400dps2_needs_64_374433_deg() -> None:
    first = _sweep_steps("accel-400")[0]
    assert first.amplitude_deg == pytest.approx(64.374433, abs=1e-6)
    assert first.id == "s109-sine-inner-0.3967Hz-400dps2"


def test_constant_position_group_grows_with_f_squared_and_skips_the_ceiling() -> None:
    steps = _sweep_steps("position-0.2deg")
    freqs = np.array([s.frequency_hz for s in steps])
    assert_allclose([s.amplitude_deg for s in steps], 0.2, rtol=0, atol=1e-12)
    assert_allclose([s.accel_dps2 for s in steps], 0.2 * (2 * np.pi * freqs) ** 2, rtol=1e-12)
    # 0.8 × 572.958 °/s² ceiling: 0.2° reaches it near 7.62 Hz, so the last 4 points go
    assert_allclose(freqs, PUBLISHED_HZ[:24], atol=1e-9)
    expansion = expand_traced(load_procedure(SHIPPED / "stepped-sine-frequency-response.yaml"))
    assert [round(s.frequency_hz, 6) for s in expansion.skipped] == [7.995605, 8.880615,
                                                                     9.002686, 9.994507]
    assert all("test_ceiling" in r or "ceiling" in r for s in expansion.skipped for r in s.reasons)
    assert expansion.to_contract_json()["skipped"][0]["group"] == "position-0.2deg"


def test_generic_rule_is_nearest_integer_and_differs_at_two_published_points() -> None:
    freqs = SweepFrequencies(start_hz=0.4, ratio=1.2, stop_hz=10, include=tuple(range(1, 10)))
    points = sweep_points(freqs, 2000.0, 131072)
    cycles = np.array([c for _, c in points])
    published = np.rint(PUBLISHED_HZ * 131072 / 2000).astype(int)
    assert len(cycles) == 28
    differs = {(int(g), int(p)) for g, p in zip(cycles, published, strict=True) if g != p}
    assert differs == {(113, 112), (162, 163)}


def test_snap_rounds_to_the_nearest_bin() -> None:
    freq_hz, cycles = snap_frequency(1.0, 2000.0, 131072)
    assert cycles == 66 and freq_hz == pytest.approx(1.007080078, abs=1e-9)
    assert snap_frequency(0.001, 2000.0, 131072)[1] == 1  # never zero cycles


def test_lab_duration_adds_soak_settle_and_record() -> None:
    plan = expand(load_procedure(SHIPPED / "temperature-steps.yaml"))
    chambers = [s for s in plan.steps if s.kind == "chamber"]
    assert len(chambers) == 15 and all(s.soak_s == 900 and s.duration_s == 0 for s in chambers)
    record_s = 131072 / 2000
    expected = 15 * (900 + (60 + record_s) + (5 + record_s))
    assert plan.lab_duration_s == pytest.approx(expected, rel=1e-12)
    assert plan.to_contract_json()["lab_duration_s"] == pytest.approx(expected)


def test_records_after_a_set_point_carry_its_temperature() -> None:
    plan = expand(load_procedure(SHIPPED / "temperature-steps.yaml"))
    kinds = [s.kind for s in plan.steps[:3]]
    assert kinds == ["chamber", "static", "sine"]
    temps = [s.temperature_c for s in plan.steps if s.kind == "static"]
    assert temps == [22, 7.5, -2, -11, -21, -14, -5, 4, 20, 29, 38, 48, 38, 29, 22]
    assert plan.steps[2].settle_s == 5 and plan.steps[1].settle_s == 60
    assert plan.steps[5].id == "s006-sine-inner-1.0071Hz-400dps2-7.5C"
    assert plan.steps[12].id == "s013-chamber-m21C"


def test_ids_are_unique_and_every_step_is_traced_to_its_entry() -> None:
    for path in sorted(SHIPPED.glob("*.yaml")):
        expansion = expand_traced(load_procedure(path))
        ids = [s.id for s in expansion.plan.steps]
        assert len(ids) == len(set(ids)), path.name
        assert set(expansion.sources) == set(ids)
        assert all(src[:2] == ("steps", 0) for src in expansion.sources.values())
        assert trace_of(expansion.plan) is expansion


def test_scale_factor_is_exactly_1hz_with_70_cycles() -> None:
    (step,) = expand(load_procedure(SHIPPED / "scale-factor.yaml")).steps
    assert step.frequency_hz == 1.0 and step.cycles == 70 and step.samples == 140000
    assert step.amplitude_deg == pytest.approx(400 / (2 * math.pi) ** 2, rel=1e-12)
    assert step.duration_s == 70.0


def test_multi_position_repeats_in_both_mountings_with_prompts() -> None:
    plan = expand(load_procedure(SHIPPED / "static-multi-position.yaml"))
    assert len(plan.steps) == 6 * 3 * 2
    assert all(s.samples == 135000 and s.duration_s == 67.5 for s in plan.steps)
    prompted = [s for s in plan.steps if s.prompt]
    assert [s.mounting.pivoted for s in prompted] == [False, True]
    assert "Pivot" in prompted[1].prompt and prompted[1].id == "s019-static-i0-o0-pivoted-r1"
    assert [s.repetition for s in plan.steps[:13:6]] == [1, 2, 3]


def test_misalignment_sets_experiments_and_remount_prompts() -> None:
    plan = expand(load_procedure(SHIPPED / "pivoted-misalignment.yaml"))
    assert len(plan.steps) == 8 * 3 * 3
    by_set = {s.mounting.scenario: [] for s in plan.steps}
    for s in plan.steps:
        by_set[s.mounting.scenario].append(s)
    assert {s.mounting.experiment for s in by_set["A"]} == {1, 2, 3}
    assert {s.mounting.experiment for s in by_set["B"]} == {4, 5, 6}
    assert all(s.mounting.pivoted for s in by_set["H"])
    assert [s.mounting.remount for s in (by_set[k][0] for k in "ACEG")] == [
        "none", "sensors", "block", "both"]
    exp3 = next(s for s in plan.steps if s.mounting.experiment == 3)
    assert (exp3.axis, exp3.inner_deg) == ("outer", 90.0)
    assert plan.steps[0].amplitude_deg == pytest.approx(2.4975, abs=1e-4)
    # A: one prompt for the set; C: a re-mount prompt before each of the 3 repetitions
    assert sum(1 for s in by_set["A"] if s.prompt) == 1
    assert sum(1 for s in by_set["C"] if s.prompt and "re-mount" in s.prompt) == 3


def test_coordinated_rates_follow_alpha_equals_omega_i_times_omega_o() -> None:
    proc = parse_procedure(
        "procedure: c\nsensor: {model: sr207}\nsteps:\n"
        "  - coordinated_rates: {frequencies_hz: [2], accelerations_dps2: [100]}\n")
    (step,) = expand(proc).steps
    omega_i = math.radians(step.rate_dps)
    omega_o = math.radians(step.outer_rate_dps)
    assert math.degrees(omega_i * omega_o) == pytest.approx(100.0, rel=1e-12)
    assert step.rate_dps == pytest.approx(360 * step.frequency_hz) and step.axis == "both"


def test_repeat_and_operator_prompts() -> None:
    proc = parse_procedure(
        "procedure: r\nsensor: {model: sr207}\nsampling: {samples: 4096}\nsteps:\n"
        "  - operator: {prompt: Check the cable}\n"
        "  - repeat:\n      count: 2\n      steps:\n"
        "        - operator: {prompt: Zero the table}\n"
        "        - constant_rate: {rates_dps: [30, -30]}\n")
    steps = expand(proc).steps
    assert [s.id for s in steps] == ["s001-rate-inner-30dps-r1", "s002-rate-inner-m30dps-r1",
                                     "s003-rate-inner-30dps-r2", "s004-rate-inner-m30dps-r2"]
    assert steps[0].prompt == "Check the cable\nZero the table"
    assert steps[2].prompt == "Zero the table" and steps[1].prompt is None
    assert [s.repetition for s in steps] == [1, 1, 2, 2]


def test_quick_variants_plan_small() -> None:
    for path in sorted(DATA.glob("quick-*.yaml")):
        plan = expand(load_procedure(path))
        assert 0 < len(plan.steps) <= 12 and all(s.samples <= 8192 for s in plan.steps), path


def test_overrides_and_explicit_cycles() -> None:
    proc = parse_procedure(
        "procedure: o\nsensor: {model: sr207}\nsampling: {samples: 8192, settle_s: 2}\nsteps:\n"
        "  - sine: {cycles: 10, amplitude_deg: 1.5, duration_s: 2.048, settle_s: 0}\n"
        "  - sine: {frequency_hz: 1.3, accel_dps2: 50, snap: none}\n")
    first, second = expand(proc).steps
    assert (first.samples, first.settle_s, first.cycles) == (4096, 0.0, 10)
    assert first.frequency_hz == pytest.approx(10 * 2000 / 4096, rel=1e-15)
    assert first.accel_dps2 == pytest.approx(1.5 * (2 * math.pi * first.frequency_hz) ** 2)
    assert first.group == "position-1.5deg" and first.id.endswith("-1.5deg")
    assert (second.frequency_hz, second.cycles, second.settle_s) == (1.3, None, 2.0)


def test_plan_json_has_the_contract_keys_and_is_stable() -> None:
    path = DATA / "quick-sine-3-steps.yaml"
    doc = expand(load_procedure(path)).to_contract_json()
    assert set(doc) == {"procedure", "steps", "lab_duration_s"}
    for step in doc["steps"]:
        assert {"id", "kind", "axis", "duration_s", "frequency_hz", "amplitude_deg",
                "accel_dps2"} <= set(step)
    assert doc == expand(load_procedure(path)).to_contract_json()
    assert [s["id"] for s in doc["steps"]] == [
        "s001-sine-inner-0.9766Hz-100dps2", "s002-sine-inner-1.9531Hz-100dps2",
        "s003-sine-inner-3.9062Hz-100dps2"]
