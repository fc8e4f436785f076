"""SR207-class servo force-balance fluid-rotor angular accelerometer (docs/method.md §1.3).

``SR207`` is one sensor (channel ``v_sz`` on the inner axis); ``SR207Unit`` the three-sensor
measurement unit (AAMU) with S_Z on I, S_Y on O and S_X on P (docs/method.md §4.5).
``default_model()`` gives the twin's realistic sensor terms, chosen so that the simulated
stepped-sine FRF matches the measured one: flat to ≈4 Hz, ≈0.6 dB down at 10 Hz, phase delay
≈13 ms (sensor ωn 30 Hz, ζ 0.9 → 9.5 ms; 100 Hz pre-sample filter 2.3 ms; 1.5 ms transport).
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict

from aatest.engine.interfaces import SensorDatasheet
from aatest.twin.model import (
    BiasTemperature,
    CrossAxis,
    GSensitivity,
    Hysteresis,
    JerkSensitivity,
    Misalignment,
    NonlinearityCubic,
    Saturation,
    ScaleTemperature,
    SensorDynamics,
    SensorModel,
    TimeDelay,
)

RANGE_DPS2 = 572.958
SCALE_V_PER_DPS2 = 0.004014

#: per-channel individual terms of the simulated units: (axis, bias_v, misalignment azimuth °)
_UNIT_CHANNELS = {"v_sz": ("I", 2.499, 30.0), "v_sy": ("O", 2.495, 150.0),
                  "v_sx": ("P", 2.502, 260.0)}


def sensor_model(channel: str = "v_sz", axis: str = "I", bias_v: float = 2.499,
                 azimuth_deg: float = 30.0) -> SensorModel:
    """One realistic SR207 channel with every datasheet term switched on."""
    return SensorModel(
        channel=channel, axis=axis, bias_v=bias_v, scale_v_per_dps2=SCALE_V_PER_DPS2,
        range_dps2=RANGE_DPS2, noise_rms_v=0.001,
        resolution_dps2=0.00005 * RANGE_DPS2,              # threshold 0.005 % FR
        bias_temperature=BiasTemperature(coefficient_v_per_c=-0.0003),  # higher when cold
        scale_temperature=ScaleTemperature(coefficient_per_c=0.0002),
        nonlinearity_cubic=NonlinearityCubic(c3=0.002),    # ≈ 0.05 % FR after a best line
        saturation=Saturation(limit_dps2=1.05 * RANGE_DPS2),
        hysteresis=Hysteresis(half_width_dps2=0.2),
        sensor_dynamics=SensorDynamics(natural_frequency_hz=30.0, damping=0.9),
        time_delay=TimeDelay(delay_s=0.0015),
        jerk_sensitivity=JerkSensitivity(coefficient_v_per_dps3=2e-8),
        g_sensitivity=GSensitivity(coefficient_dps2_per_g=0.573),  # 0.01 rad/s²/g
        cross_axis=CrossAxis(ratio_x=0.003, ratio_y=-0.002),
        misalignment=Misalignment(angle_deg=0.2, azimuth_deg=azimuth_deg),
    )


def default_models_for(name: str) -> list[SensorModel]:
    """Realistic sensor models for the plugin name ``sr207`` or ``sr207-aamu``."""
    if name == "sr207":
        return [sensor_model()]
    if name in ("sr207-aamu", "sr207unit"):
        return [sensor_model(ch, ax, b, az) for ch, (ax, b, az) in _UNIT_CHANNELS.items()]
    raise KeyError(f"unknown sensor model {name!r}; expected 'sr207' or 'sr207-aamu'")


class _Sensor:
    """Common plugin behaviour; subclasses set the channel map."""

    channels_map: dict[str, str] = {"v_sz": "I"}
    plugin_name = "sr207"

    class Config(BaseModel):
        model_config = ConfigDict(extra="forbid")

    def __init__(self, config: BaseModel | None = None, context: Any = None) -> None:
        self.config = config if config is not None else self.Config()
        self.context = context

    def datasheet(self) -> SensorDatasheet:
        """Datasheet values of docs/method.md §1.3."""
        return SensorDatasheet(
            model=self.plugin_name, range_dps2=RANGE_DPS2, nominal_bias_v=2.5,
            bias_tolerance_v=0.01, scale_v_per_dps2=SCALE_V_PER_DPS2, scale_tolerance_pct=1.0,
            noise_rms_v=0.003, test_ceiling_fraction=0.8, floor_dps2=0.8,
            bias_temperature_limit_v_per_c=0.0004, scale_temperature_limit_per_c=0.0005,
            cross_axis_limit=0.01, misalignment_limit_deg=0.5, channels=dict(self.channels_map))

    def default_model(self) -> list[SensorModel]:
        """The twin's default (realistic) sensor terms for this model."""
        return default_models_for(self.plugin_name)


class SR207(_Sensor):
    """A single SR207 on the inner axis (channel ``v_sz``)."""

    class Config(BaseModel):
        model_config = ConfigDict(extra="forbid")


class SR207Unit(_Sensor):
    """Three SR207 on a mounting block: S_Z on I, S_Y on O, S_X on P."""

    channels_map = {"v_sz": "I", "v_sy": "O", "v_sx": "P"}
    plugin_name = "sr207-aamu"

    class Config(BaseModel):
        model_config = ConfigDict(extra="forbid")
