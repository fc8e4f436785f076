"""The sensor datasheet and the per-channel sensor record: every sensor number defined once.

A sensor plugin describes a sensor *model* with one :class:`SensorDatasheet`; the engine turns
it into one :class:`SensorInfo` per channel (:meth:`SensorDatasheet.sensor_infos`). That record
is what a recording stores in its metadata, what ``dataset.yaml`` of the import format lists
under ``sensors`` (docs/interfaces.md §3) and what every analysis reads from the
:class:`~aatest.recording.dataset.Dataset`. Both models take the per-channel fields from
:class:`SensorNominals`, so each number has one name, one unit and one default.

The defaults describe the reference sensor class of docs/method.md §1.3 (the SR207-class servo
force-balance fluid-rotor accelerometer): what aatest assumes about a sensor nobody described.
The per-channel record and those numbers live in :mod:`aatest.results.sensor` (the typed
results carry the sensors) and are re-exported here; everything else (the SR207 plugin, the
twin, the uncertainty stage) takes them from there.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from pydantic import Field, model_validator

from aatest.results.sensor import (
    REFERENCE_BIAS_V,
    REFERENCE_RANGE_DPS2,
    REFERENCE_SCALE_V_PER_DPS2,
    SensorAxis,
    SensorInfo,
    SensorNominals,
)

__all__ = ["REFERENCE_BIAS_V", "REFERENCE_RANGE_DPS2", "REFERENCE_SCALE_V_PER_DPS2",
           "SensorAxis", "SensorDatasheet", "SensorInfo", "SensorNominals"]

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
    #: (lowest, highest) temperature the sensor may be taken to, °C (docs/method.md §1.3:
    #: −40 to 85 °C): a chamber set-point outside it is refused before anything moves
    operating_temperature_c: tuple[float, float] = (-40.0, 85.0)
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
