"""The converter diagnose assumes is the logger the data state (docs/interfaces.md §4).

A backlash whose dead band in volts lies within one converter step lies where the logger's own
transfer is not characterised, so the stated converter decides what ``hysteresis`` may name.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from multi_dataset import write_multi

from aatest.diagnose.logger_chain import stated_converter
from aatest.diagnose.pipeline import diagnose_dataset
from aatest.diagnose.scenarios import Hidden, clean_rig, diagnostic_plan, with_effects
from aatest.recording.reader import read_dataset
from aatest.twin.api import simulate_dataset

#: K of the scenarios' sensor (V per °/s²), the twin's default
K_V_PER_DPS2 = 0.004014


def test_the_rig_descriptions_logger_comes_first(tmp_path: Path) -> None:
    """An import stating a 12-bit ±5 V logger: q = 10 V / 4096 = 2.44 mV, from that file."""
    data = write_multi(tmp_path / "data", samples=4096, seed=1)
    manifest = data / "dataset.yaml"
    manifest.write_text(manifest.read_text()
                        + "instruments:\n  logger: {bits: 12, range_v: [-5.0, 5.0]}\n")
    spec, source = stated_converter(read_dataset(data))
    assert (spec.bits, tuple(spec.range_v)) == (12, (-5.0, 5.0))
    # exact on any CPU: (5 − (−5)) and the division by 2**12 are exact in binary floats
    assert spec.step_v == 10.0 / 4096
    assert source == "rig description"


def test_without_a_stated_logger_the_stated_default_applies(tmp_path: Path) -> None:
    spec, source = stated_converter(read_dataset(write_multi(tmp_path / "d", samples=4096)))
    # ±10 V, 16 bit: 305 µV, exact on any CPU (20 / 2**16 is a power-of-two division)
    assert spec.step_v == 20.0 / 2**16
    assert source.startswith("stated default")


def test_a_simulations_converter_is_its_rig_models() -> None:
    rig = clean_rig(1)
    rig = rig.model_copy(update={"daq": rig.daq.model_copy(update={"adc_bits": 24})})
    data = simulate_dataset(rig, diagnostic_plan(4096)[:2], 1)
    spec, source = stated_converter(data)
    assert spec.bits == 24
    assert source == "the data's rig model"


def _with_converter(bits: int, hidden: list[Hidden], seed: int, samples: int):
    rig = with_effects(clean_rig(seed), hidden)
    rig = rig.model_copy(update={"daq": rig.daq.model_copy(update={"adc_bits": bits})})
    data = simulate_dataset(rig, diagnostic_plan(samples), seed, procedure="diagnose-scenario")
    return data


@pytest.mark.slow
def test_a_play_within_one_converter_step_is_not_hysteresis() -> None:
    """A play of 0.03 °/s² (dead band 2·r·K = 241 µV) under 1 mV noise: below the 305 µV step
    of a 16-bit ±10 V logger it is refused with that reason (without the rule the dithered
    fit names it, r = 0.029, ΔBIC −87); the same play recorded by a 24-bit logger
    (q = 1.2 µV) is named, within 25 % (the suite's tolerance)."""
    r = 0.03
    hidden = [Hidden("hysteresis", {"half_width_dps2": r}, ("half_width_dps2",))]
    assert 2 * r * K_V_PER_DPS2 < 20.0 / 2**16
    coarse = diagnose_dataset(_with_converter(16, hidden, 41, 2**13))
    row = next(c for c in coarse["candidates"] if c["effect"] == "hysteresis")
    assert "hysteresis" not in [f["effect"] for f in coarse["findings"]]
    assert "within one step of the stated converter" in row["reason"]
    assert coarse["logger"]["converter"]["bits"] == 16
    fine = diagnose_dataset(_with_converter(24, hidden, 41, 2**13))
    named = [f for f in fine["findings"] if f["effect"] == "hysteresis"]
    assert named, fine["candidates"]
    assert named[0]["parameters"]["half_width_dps2"] == pytest.approx(r, rel=0.25)



def test_steps_the_logger_clipped_are_left_out_of_the_diagnosis() -> None:
    """A 0…3.6 V logger under the 400 °/s² sines (2.5 V ± 1.6 V) holds their tops at its top
    code. Fitted, those flat tops made the clean twin's diagnosis name a cubic non-linearity
    (c3 ≈ −0.44) the sensor does not have; the clipped steps are left out and named, and the
    rest of the plan shows nothing to explain."""
    rig = clean_rig(3)
    rig = rig.model_copy(update={"daq": rig.daq.model_copy(update={"adc_range_v": (0.0, 3.6)})})
    data = simulate_dataset(rig, diagnostic_plan(2**12), 3, procedure="diagnose-scenario")
    top = {s.step.id: s.daq.channels["v_sz"].max() for s in data.steps}
    # the top code 2^16 − 1 of the 0…3.6 V converter, q = 3.6 V / 2^16: a sample is code·q
    # in float64, a few ulp (~1e-15 V) from 3.6 − q; half a step (27 µV) tells codes apart
    q_v = 3.6 / 2**16
    at_rail = {step for step, v in top.items() if abs(v - (3.6 - q_v)) < q_v / 2}
    assert at_rail == {s.step.id for s in data.steps if (s.step.accel_dps2 or 0) >= 300}
    doc = diagnose_dataset(data)
    assert set(doc["steps_clipped"]) == at_rail
    assert all(at["v_sz"] > 0 for at in doc["steps_clipped"].values())
    assert doc["findings"] == [], doc["findings"]
