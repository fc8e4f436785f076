"""The sensor's output stage gives the very volts of its plain formulation, bit for bit.

``output_volts`` now forms the cubic nonlinearity, the temperature-dependent scale and bias,
the jerk terms and the sums in place; ``damping_of`` and the g-sensitivity term likewise. Each
performs the same IEEE operations on the same operands as the expressions it replaced (x² is
x·x, a·b and a + b commute, np.gradient's own differences), so the check is equality: a
last-bit change would flip ADC codes of the recording.
"""

from __future__ import annotations

import numpy as np
import pytest

from aatest.plugins.sensors.sr207 import SR207Unit
from aatest.twin import sensor as sn
from aatest.twin import sensor_output
from aatest.twin.api import realistic_rig_model
from aatest.twin.model import SensorModel

DT_S = 1.0 / 2000.0
T_REF_C = 25.0


def _sensor() -> SensorModel:
    """The realistic datasheet channel: every term of the output stage switched on."""
    model = realistic_rig_model(SR207Unit().datasheet()).sensors[0]
    assert model.nonlinearity_cubic is not None and model.scale_temperature is not None
    assert model.jerk_sensitivity is not None and model.jerk_distortion is not None
    return model


def _inputs(n: int, seed: int) -> sn.SensorInputs:
    """A 4 Hz, 650 °/s² sine (into saturation) about a slightly tilted axis, with noise,
    on a warming sensor."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * DT_S
    alpha = np.zeros((3, n))
    alpha[2] = 650.0 * np.sin(2 * np.pi * 4.0 * t) + rng.standard_normal(n)
    alpha[0] = 0.5 * rng.standard_normal(n)
    up = np.vstack([1e-3 * np.sin(t), 1e-3 * np.cos(t), np.ones(n)])
    c, s = np.cos(0.003), np.sin(0.003)
    axes = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    return sn.SensorInputs(alpha, up, 23.0 + 0.01 * t, axes, DT_S, t)


def _reference_volts(model: SensorModel, inp: sn.SensorInputs, state: sn.ChannelState
                     ) -> np.ndarray:
    """``output_volts`` as first written (no stiction, no plugin effects in this model)."""
    axis = inp.axes[:, 2] + model.cross_axis.ratio_x * inp.axes[:, 0] \
        + model.cross_axis.ratio_y * inp.axes[:, 1]
    sensed = axis @ inp.alpha_top_dps2
    sensed += model.g_sensitivity.coefficient_dps2_per_g * (inp.axes[:, 2] @ inp.up_g)
    sensed = sn.play_operator(sensed, model.hysteresis.half_width_dps2, state.play_dps2)
    state.play_dps2 = float(sensed[-1])
    alpha = response = sn.amplitude_dynamics(model, sensed, inp.dt_s, state)
    lim = model.saturation.limit_dps2
    alpha = np.clip(alpha, -lim, lim)
    alpha = np.round(alpha / model.resolution_dps2) * model.resolution_dps2
    d_temp = inp.temperature_c - T_REF_C
    alpha = alpha * (1.0 + model.nonlinearity_cubic.c3 * (alpha / model.range_dps2) ** 2)
    plugin_volts = np.zeros_like(alpha)
    scale = model.scale_v_per_dps2 * (1.0 + model.scale_temperature.coefficient_per_c * d_temp)
    volts = model.bias_v + scale * alpha
    volts = volts + model.bias_temperature.coefficient_v_per_c * d_temp
    volts = volts + sn.bias_drift_v(model.bias_drift, volts.size, inp.dt_s, state)
    jerk = model.jerk_sensitivity.coefficient_v_per_dps3 * np.gradient(sensed, inp.dt_s)
    jerk = jerk + model.jerk_distortion.coefficient_v_per_dps3_squared * np.gradient(
        response, inp.dt_s) ** 2
    return volts + jerk + plugin_volts


def test_output_volts_in_place_equals_the_plain_formulas() -> None:
    model = _sensor()
    inp = _inputs(30_000, seed=5)
    mine, plain = (sn.ChannelState(drift_rng=np.random.default_rng(9)) for _ in range(2))
    for block in range(2):  # the second block continues every carried state
        fast = sn.output_volts(model, inp, T_REF_C, mine)
        assert np.array_equal(fast, _reference_volts(model, inp, plain)), block


@pytest.mark.parametrize("n", [2, 3, 1001])
def test_gradient_is_numpys(n: int) -> None:
    x = np.random.default_rng(n).standard_normal(n).cumsum()
    assert np.array_equal(sensor_output.gradient(x, DT_S), np.gradient(x, DT_S))


def test_damping_of_in_place_equals_the_plain_formula() -> None:
    model = _sensor()
    effect, damping = model.amplitude_damping, model.sensor_dynamics.damping
    amplitude = np.geomspace(1e-12, 1e4, 2001)  # through the floor and both bounds
    plain = np.clip(damping + effect.damping_per_decade * np.log10(
        np.maximum(amplitude, 1e-9) / effect.reference_dps2), 0.05, 5.0)
    assert np.array_equal(sn.damping_of(effect, damping, amplitude), plain)
    # at the reference amplitude A/ref is 1.0 and log10(1.0) is 0.0, both exact in IEEE 754
    # on every CPU, so ζ comes back unchanged: an exact comparison, not a tolerance
    assert sn.damping_of(effect, damping, effect.reference_dps2) == damping
