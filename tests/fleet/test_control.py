"""I-MR control limits and Western Electric rules against hand computations."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

import numpy as np
import pytest

from aatest.fleet.control import ControlChart, control_chart

T0 = datetime(2025, 1, 1, tzinfo=UTC)


def _chart(values: list[float] | np.ndarray) -> ControlChart:
    n = len(values)
    chart = control_chart("scale_factor.v_sz", "sr207", None,
                          [T0 + timedelta(days=i) for i in range(n)],
                          [f"U{i}" for i in range(n)], values)
    assert chart is not None
    return chart


def test_limits_match_the_hand_computation() -> None:
    chart = _chart([10.0, 12.0, 11.0, 13.0, 12.0])
    # By hand: x̄ = 58 / 5 = 11.6; moving ranges 2, 1, 2, 1 → MR̄ = 1.5;
    # σ̂ = 1.5 / 1.128 = 1.329787; limits 11.6 ∓ 3.989362 = 7.610638 … 15.589362;
    # MR upper limit 3.267 · 1.5 = 4.9005.
    # sums of five small numbers: only rounding separates them (1e-9 relative is ample)
    assert chart.center == pytest.approx(11.6, rel=1e-9)
    assert chart.mr_bar == pytest.approx(1.5, rel=1e-9)
    assert chart.sigma == pytest.approx(1.5 / 1.128, rel=1e-9)
    assert chart.limits == pytest.approx((11.6 - 4.5 / 1.128, 11.6 + 4.5 / 1.128), rel=1e-9)
    assert chart.mr_ucl == pytest.approx(4.9005, rel=1e-9)
    assert chart.signals == ()


def test_an_injected_outlier_is_flagged_by_rule_1() -> None:
    values = np.random.default_rng(20261126).normal(0.004014, 2e-6, 25)
    values[12] += 12e-6  # six process sigmas
    chart = _chart(values)
    assert [s.index for s in chart.signals if s.rule == "rule 1"] == [12]
    # the jump into and out of the outlier are the moving ranges above D₄·MR̄
    assert {s.index for s in chart.signals if s.rule == "MR"} <= {12, 13}
    assert 12 in chart.flagged()


def test_a_shift_of_eight_points_is_flagged_by_the_run_rule() -> None:
    # ten points alternating about 0, then eight at +0.5: inside ±3σ̂ but all above the centre
    values = [0.3, -0.3] * 5 + [0.5] * 8
    chart = _chart(values)
    # by hand: x̄ = 4 / 18 = 0.2222; the last eight points lie above it, so the eighth
    # consecutive one (index 17) is the first that rule 4 flags
    assert [s.index for s in chart.signals if s.rule == "rule 4"] == [17]
    assert not [s for s in chart.signals if s.rule == "rule 1"]


def test_two_of_three_beyond_two_sigma_are_flagged_by_rule_2() -> None:
    values = [0.0, 0.2] * 10 + [0.65, 0.1, 0.65]
    chart = _chart(values)
    # By hand: x̄ = 3.4 / 23 = 0.147826; moving ranges 19 × 0.2, then 0.45, 0.55, 0.55 →
    # MR̄ = 5.35 / 22 = 0.243182; σ̂ = 0.215587, 2σ̂ = 0.431173, 3σ̂ = 0.646760.
    # 0.65 − x̄ = 0.502174 lies between 2σ̂ and 3σ̂: indices 20 and 22 are two of three
    # beyond 2σ̂ on the upper side; no point beyond 3σ̂, no moving range above 0.794475.
    assert chart.mr_bar == pytest.approx(5.35 / 22, rel=1e-9)
    assert [s.index for s in chart.signals if s.rule == "rule 2"] == [20, 22]
    assert [s.rule for s in chart.signals] == ["rule 2", "rule 2"]


def test_constant_values_are_in_control() -> None:
    assert _chart([1.0] * 10).signals == ()


def test_fewer_than_three_points_make_no_chart() -> None:
    assert control_chart("q", "m", None, [T0, T0], ["a", "b"], [1.0, 2.0]) is None


def test_charts_per_rig_only_for_a_model_seen_on_several_rigs() -> None:
    from aatest.fleet.analysis import fleet_charts
    from aatest.fleet.archive import FleetRecord
    from aatest.records.models import CalibrationRecord, QuantityRecord

    def row(i: int, model: str, rig: str) -> FleetRecord:
        when = T0 + timedelta(days=i)
        return FleetRecord(CalibrationRecord(
            id=i, model=model, serial=f"S{i}", certificate_number=None, supersedes_id=None,
            superseded_by=None, command="run", procedure="p", procedure_sha256=None,
            operator=None, lab="L", calibrated_utc=when, registered_utc=when,
            overall_verdict="pass", verdicts=[], bundle=f"/b/{i}", key_fingerprint=None,
            files={}, quantities={"bias.v_sz": QuantityRecord(value=2.5 + 0.001 * (i % 3),
                                                               unit="V")},
            rig={}, plugin_versions={}), rig)

    rows = [row(i, "m1", "T1" if i % 2 else "T2") for i in range(8)]
    rows += [row(10 + i, "m2", "T1") for i in range(3)] + [row(20, "m3", "T1")]
    charts, short = fleet_charts(rows)
    assert [(c.model, c.rig) for c in charts] == [("m1", None), ("m1", "T1"), ("m1", "T2"),
                                                  ("m2", None)]
    assert short == 1  # m3 has one calibration
