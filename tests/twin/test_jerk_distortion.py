"""``jerk_distortion``: a second harmonic c·(2πf·A)²/2 in volts, nothing at the fundamental.

The effect is switched on from a model YAML on the nominal rig (1 mV noise) and read back
from the logged output (its coefficient: test_effects.py): its second harmonic against
c·(ωA·|H|)²/2, and the fundamental against the same rig without it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from twin_steps import aligned_daq, fundamental, model_from_yaml, sine_step

from aatest.twin.api import nominal_rig_model, simulate_step
from aatest.twin.model import RigModel

#: V per (°/s³)²: 4.2 % second harmonic at 8 Hz, 300 °/s² (the realistic default is 2.1e-10)
C_V = 1e-9


def _rig(tmp_path: Path, dynamics: dict | None = None) -> tuple[RigModel, RigModel]:
    """(with the distortion, without) on the nominal rig with a 1 mV noise floor."""
    nominal = nominal_rig_model()
    base = nominal.model_copy(update={"sensors": [nominal.sensors[0].model_copy(
        update={"noise_rms_v": 0.001})]})
    extra = {"sensor_dynamics": dynamics} if dynamics else {}
    on = model_from_yaml(tmp_path, base, sensor={
        "jerk_distortion": {"coefficient_v_per_dps3_squared": C_V}, **extra})
    off = model_from_yaml(tmp_path, base, sensor=extra)
    return on, off


@pytest.mark.parametrize("dynamics", [None, {"natural_frequency_hz": 30.0, "damping": 0.7}],
                         ids=["no dynamics", "30 Hz dynamics"])
def test_second_harmonic_without_touching_the_fundamental(tmp_path: Path,
                                                          dynamics: dict | None) -> None:
    """At 8 Hz and 300 °/s² the second harmonic is c·(ωA·|H|)²/2 (H the dynamics at 8 Hz:
    the term acts on the rotor's response) and the fundamental is the one without the
    effect. Tolerances: 3 % on the harmonic (≈ 24 mV against a 1 mV noise floor spread over
    16 384 samples, and np.gradient's (ωh)²/6 = 1e-4 bias); 1e-4 relative on the fundamental
    (the same noise realisation, 1.2 V amplitude)."""
    on, off = _rig(tmp_path, dynamics)
    step = sine_step(8.0, 300.0, samples=16384)
    with_, without = (aligned_daq(simulate_step(m, step, 3), "v_sz") for m in (on, off))
    assert step.cycles is not None and step.frequency_hz is not None
    w = 2 * np.pi * step.frequency_hz
    h = 1.0
    if dynamics:
        wn, z = 2 * np.pi * dynamics["natural_frequency_hz"], dynamics["damping"]
        h = abs(wn**2 / (wn**2 - w**2 + 2j * z * wn * w))
    expected_v = C_V * (w * 300.0 * h) ** 2 / 2
    assert abs(fundamental(with_, 2 * step.cycles)) == pytest.approx(expected_v, rel=0.03)
    assert abs(fundamental(with_, step.cycles)) == pytest.approx(
        abs(fundamental(without, step.cycles)), rel=1e-4)
