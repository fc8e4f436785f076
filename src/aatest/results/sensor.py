"""The per-channel sensor record of a run (``metadata.sensors``) and its datasheet nominals.

Defined here, beside the other result models, so the typed results can carry the sensors they
were measured with (:class:`SensorInfo`); :mod:`aatest.engine.datasheet` builds them from a
sensor model's datasheet. The ``REFERENCE_*`` numbers describe the reference sensor class of
docs/method.md §1.3 and are the only statement of those datasheet numbers in ``src/``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

__all__ = ["REFERENCE_BIAS_V", "REFERENCE_RANGE_DPS2", "REFERENCE_SCALE_V_PER_DPS2",
           "SensorAxis", "SensorInfo", "SensorNominals"]

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


#: a sensor record's model or serial when nothing states it
UNSTATED = "unknown"


class SensorInfo(SensorNominals):
    """One sensor channel as the engine records it and the analyses read it."""

    channel: str = Field(min_length=1)
    axis: SensorAxis = "I"
    model: str = UNSTATED
    serial: str = UNSTATED

    @classmethod
    def from_metadata(cls, entry: Mapping[str, Any]) -> SensorInfo:
        """Read a record stored in a recording's metadata, ignoring keys this version lacks.

        Recordings written by other versions may carry more (or fewer) keys; the ones this
        record knows are validated, missing ones take the datasheet defaults.
        """
        return cls(**{k: v for k, v in entry.items() if k in cls.model_fields})
