"""``rotor_stiction`` in diagnose's vocabulary (issue 28): found blind, not claimed otherwise.

The twin hides a stiction gap (:func:`draw_rotor_stiction`, seeded) in the diagnostic plan;
diagnose must name it with its break-away rate and depth within 25 % (``judge``) and the twin
must take the written model back. Data without the gap must not be claimed to have it: clean
data (``test_clean_data_gives_no_finding_and_exit_0`` in test_diagnose_hidden_effects.py runs
every candidate, this one included) and data with the effects whose signature is nearest —
hysteresis (a loss at small amplitude, but with a lag) and second-order dynamics (a loss
growing with frequency, with a lag). Each diagnosis takes 20–130 s on a loaded machine, so
they run under ``-m slow``.
"""

from __future__ import annotations

import pytest

from aatest.diagnose.scenarios import draw_rotor_stiction, judge
from aatest.twin.model import load_rig_model

QUICK = 2**13


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2])
def test_hidden_rotor_stiction_is_found_with_its_parameters(run_diagnose, seed: int,
                                                           tmp_path) -> None:
    hidden = [draw_rotor_stiction(seed)]
    code, doc = run_diagnose(hidden, seed=seed, samples=QUICK)
    assert judge(doc, hidden) == []
    assert code == 1
    finding = next(f for f in doc["findings"] if f["effect"] == "rotor_stiction")
    for key in ("breakaway_rate_dps", "depth"):
        lo, hi = finding["ci95"][key]
        assert lo <= finding["parameters"][key] <= hi
    sensor = load_rig_model(tmp_path / "model.yaml").sensors[0]  # the twin takes it back
    assert sensor.rotor_stiction is not None
    assert sensor.rotor_stiction.depth == pytest.approx(hidden[0].parameters["depth"], rel=0.25)


@pytest.mark.slow
@pytest.mark.parametrize("effect", ["hysteresis", "sensor_dynamics"])
def test_look_alikes_are_not_rotor_stiction(not_claimed_as, effect: str) -> None:
    not_claimed_as("rotor_stiction", effect, seed=5, samples=QUICK)
