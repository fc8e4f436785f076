"""The sensor datasheet and the per-channel sensor record: every sensor number defined once.

A sensor plugin describes a sensor *model* with one :class:`SensorDatasheet`; the engine turns
it into one :class:`SensorInfo` per channel (:meth:`SensorDatasheet.sensor_infos`). That record
is what a recording stores in its metadata, what ``dataset.yaml`` of the import format lists
under ``sensors`` (docs/interfaces.md §3) and what every analysis reads from the
:class:`~aatest.engine.dataset.Dataset`. Both models take the per-channel fields from
:class:`SensorNominals`, so each number has one name, one unit and one default.

The defaults describe the reference sensor class of docs/method.md §1.3 (the SR207-class servo
force-balance fluid-rotor accelerometer): what aatest assumes about a sensor nobody described.
This module is the only place in ``src/`` that states those datasheet numbers; everything else
(the SR207 plugin, the twin, report fall-backs) takes them from here.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

__all__ = ["REFERENCE_BIAS_V", "REFERENCE_RANGE_DPS2", "REFERENCE_SCALE_V_PER_DPS2",
           "SensorAxis", "SensorDatasheet", "SensorInfo", "SensorNominals"]

SensorAxis = Literal["I", "O", "P"]

#: range of the reference sensor, °/s² (±10 rad/s², docs/method.md §1.3)
REFERENCE_RANGE_DPS2 = 572.958
#: scale factor of the reference sensor, V/(°/s²) (0.23 V/(rad/s²) = 4.014 mV/(°/s²))
REFERENCE_SCALE_V_PER_DPS2 = 0.004014
#: zero-acceleration output of the reference sensor, V
REFERENCE_BIAS_V = 2.5


class SensorNominals(BaseModel):
    """Datasheet values every channel of a sensor model carries (nominals and limits).

    Units are in the names: volts, °/s², per cent, per °C.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")
    range_dps2: float = Field(REFERENCE_RANGE_DPS2, gt=0, description="±full scale, °/s²")
    nominal_bias_v: float = Field(REFERENCE_BIAS_V, description="output at rest, V")
    nominal_scale_v_per_dps2: float = Field(REFERENCE_SCALE_V_PER_DPS2, gt=0,
                                            description="scale factor, V/(°/s²)")
    noise_rms_v: float = Field(0.003, ge=0, description="output noise limit, V RMS")
    bias_tolerance_v: float = Field(0.01, ge=0, description="bias band around the nominal, V")
    scale_tolerance_pct: float = Field(1.0, ge=0, description="scale-factor band, %")
    bias_temperature_limit_v_per_c: float = Field(0.0004, ge=0,
                                                  description="null shift limit, V/°C")
    scale_temperature_limit_per_c: float = Field(0.0005, ge=0,
                                                 description="relative scale shift limit, 1/°C")


class SensorInfo(SensorNominals):
    """One sensor channel as the engine records it and the analyses read it."""

    channel: str = Field(min_length=1)
    axis: SensorAxis = "I"
    model: str = "unknown"
    serial: str = "unknown"

    @classmethod
    def from_metadata(cls, entry: Mapping[str, Any]) -> SensorInfo:
        """Read a record stored in a recording's metadata, ignoring keys this version lacks.

        Recordings written by other versions may carry more (or fewer) keys; the ones this
        record knows are validated, missing ones take the datasheet defaults.
        """
        return cls(**{k: v for k, v in entry.items() if k in cls.model_fields})


#: the channels of a single-axis sensor: one channel, sensitive about the inner axis
_SINGLE_AXIS: Mapping[str, SensorAxis] = {"v_sz": "I"}


class SensorDatasheet(SensorNominals):
    """Datasheet of a sensor model: the envelope and the nominals analyses compare against.

    ``scale_v_per_dps2`` is accepted (and readable) as the older name of
    ``nominal_scale_v_per_dps2``.
    """

    model: str
    #: fraction of range a test may command (docs/method.md §4.4: 80 %)
    test_ceiling_fraction: float = Field(0.8, gt=0, le=1)
    #: smallest useful peak acceleration (noise floor, docs/method.md §4.4: 0.8 °/s²)
    floor_dps2: float = Field(0.8, ge=0)
    cross_axis_limit: float = Field(0.01, ge=0)
    misalignment_limit_deg: float = Field(0.5, ge=0)
    #: None: 0.1 % FR/g or 0.01 rad/s²/g, whichever is greater (docs/method.md §1.3)
    g_sensitivity_limit_dps2_per_g: float | None = None
    #: non-linearity limit, % of full range (docs/method.md §1.3: ±0.05 % FR)
    nonlinearity_limit_pct_fr: float = 0.05
    #: channel name → sensitive axis in the table frame (I, O, P)
    channels: Mapping[str, SensorAxis] = Field(default_factory=lambda: _SINGLE_AXIS)

    @model_validator(mode="before")
    @classmethod
    def _older_scale_name(cls, data: Any) -> Any:
        if isinstance(data, Mapping) and "scale_v_per_dps2" in data:
            data = dict(data)
            if "nominal_scale_v_per_dps2" in data:
                raise ValueError("give nominal_scale_v_per_dps2 or scale_v_per_dps2, not both")
            data["nominal_scale_v_per_dps2"] = data.pop("scale_v_per_dps2")
        return data

    @property
    def scale_v_per_dps2(self) -> float:
        """The nominal scale factor, V/(°/s²) (older name of ``nominal_scale_v_per_dps2``)."""
        return self.nominal_scale_v_per_dps2

    def sensor_infos(self, serial: str) -> tuple[SensorInfo, ...]:
        """One record per channel of this model, for the unit with serial number ``serial``."""
        nominals = self.model_dump(include=set(SensorNominals.model_fields))
        return tuple(SensorInfo(channel=channel, axis=axis, model=self.model, serial=serial,
                                **nominals)
                     for channel, axis in self.channels.items())
