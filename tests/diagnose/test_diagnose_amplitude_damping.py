"""``amplitude_damping`` in diagnose's vocabulary (issue 28): found blind, not claimed otherwise.

The effect varies the damping of ``sensor_dynamics`` with the acceleration amplitude, so the
twin hides it together with the dynamics (:func:`draw_amplitude_damping`, seeded) and both
must be named with their parameters within 25 % (``judge``). Diagnose's nominal model is the
datasheet's ideal chain — no dynamics, so no amplitude damping either (docs/interfaces.md §4):
data without the effect — clean, with plain (fixed-ζ) dynamics, or with hysteresis, which
also lags more at small amplitude — must not be claimed to have it.
"""

from __future__ import annotations

import pytest

from aatest.diagnose.scenarios import draw_amplitude_damping, draw_hidden, judge
from aatest.twin.model import load_rig_model

QUICK = 2**13


def _row(doc: dict, effect: str) -> dict:
    return next(r for r in doc["candidates"] if r["effect"].split("#")[0] == effect)


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_hidden_amplitude_damping_is_found_with_its_slope(run_diagnose, seed: int,
                                                          tmp_path) -> None:
    hidden = draw_amplitude_damping(seed)
    code, doc = run_diagnose(hidden, seed=seed, samples=QUICK)
    assert judge(doc, hidden) == []
    assert code == 1
    finding = next(f for f in doc["findings"] if f["effect"] == "amplitude_damping")
    lo, hi = finding["ci95"]["damping_per_decade"]
    assert lo < finding["parameters"]["damping_per_decade"] < hi
    sensor = load_rig_model(tmp_path / "model.yaml").sensors[0]  # the twin takes it back
    assert sensor.amplitude_damping is not None and sensor.sensor_dynamics is not None
    assert sensor.amplitude_damping.reference_dps2 == 10.0


@pytest.mark.slow
def test_fixed_damping_dynamics_are_not_amplitude_damping(run_diagnose) -> None:
    hidden = [draw_amplitude_damping(4)[0]]  # the same dynamics, ζ the same at every amplitude
    _, doc = run_diagnose(hidden, seed=4, samples=QUICK)
    assert judge(doc, hidden) == []
    assert _row(doc, "amplitude_damping")["testable"] is True


@pytest.mark.slow
def test_hysteresis_is_not_amplitude_damping(run_diagnose) -> None:
    hidden = [draw_amplitude_damping(5)[0], draw_hidden("hysteresis", 5)]
    _, doc = run_diagnose(hidden, seed=5, samples=QUICK)
    assert judge(doc, hidden) == []


def test_without_dynamics_amplitude_damping_waits_for_them(run_diagnose) -> None:
    hidden = [draw_hidden("time_delay", 6)]  # a lag, at every amplitude the same
    _, doc = run_diagnose(hidden, seed=6, samples=QUICK)
    assert judge(doc, hidden) == []
    row = _row(doc, "amplitude_damping")
    assert row["testable"] is False and "sensor_dynamics" in row["reason"]
