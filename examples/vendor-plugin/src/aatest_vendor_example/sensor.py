"""A MEMS angular accelerometer: what a vendor writes to describe a new sensor model.

A sensor plugin only has to return its datasheet: the planner takes the range, test ceiling
and noise floor from it, the analyses compare against its nominals and tolerances.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

from aatest.engine.interfaces import SensorDatasheet


class MemsAngularAccelerometer:
    """ACME AA-2000: ±2000 °/s², 1.0 mV/(°/s²) around a 2.5 V bias, one axis (``v_sz``)."""

    class Config(BaseModel):
        """No options are needed; ``range_dps2`` selects the range variant."""

        model_config = ConfigDict(extra="forbid")
        range_dps2: float = Field(2000.0, gt=0)

    def __init__(self, config: Config | None = None, context: None = None) -> None:
        # sensor plugins are constructed as ``Cls(config, None)``: a datasheet needs no rig
        self.config = config if config is not None else self.Config()

    def datasheet(self) -> SensorDatasheet:
        """Datasheet of the selected range (scale 2 V over the full range)."""
        full_range = self.config.range_dps2
        return SensorDatasheet(
            model="acme-mems-aa", range_dps2=full_range, nominal_bias_v=2.5,
            bias_tolerance_v=0.02, scale_v_per_dps2=2.0 / full_range, scale_tolerance_pct=2.0,
            noise_rms_v=0.002, test_ceiling_fraction=0.8, floor_dps2=2.0,
            bias_temperature_limit_v_per_c=0.001, scale_temperature_limit_per_c=0.0003,
            cross_axis_limit=0.02, misalignment_limit_deg=1.0, channels={"v_sz": "I"})
