"""The one input every analysis reads: steps with their two raw logs and the sensors' nominals.

A :class:`Dataset` is built either from an aatest recording (``recording.mcap``) or from a
measured-data import directory (docs/interfaces.md §3), so analyses and ``diagnose`` never care
where the data came from and can always be re-run offline.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any, Literal

from aatest.engine.logs import SampledLog
from aatest.engine.steps import PlannedStep

SensorAxis = Literal["I", "O", "P"]


@dataclass(frozen=True)
class SensorInfo:
    """Nominal (datasheet) description of one sensor channel."""

    channel: str
    axis: SensorAxis = "I"
    nominal_bias_v: float = 2.5
    nominal_scale_v_per_dps2: float = 0.004014
    range_dps2: float = 572.958
    model: str = "unknown"
    serial: str = "unknown"
    noise_rms_v: float = 0.003
    bias_tolerance_v: float = 0.01
    scale_tolerance_pct: float = 1.0
    bias_temperature_limit_v_per_c: float = 0.0004
    scale_temperature_limit_per_c: float = 0.0005


@dataclass(frozen=True)
class StepData:
    """One recorded step: what was commanded and what both loggers saw."""

    step: PlannedStep
    table: SampledLog
    daq: SampledLog


@dataclass(frozen=True)
class Dataset:
    """Everything an analysis may read."""

    procedure: str
    sample_rate_hz: float
    sensors: tuple[SensorInfo, ...]
    steps: tuple[StepData, ...]
    source: Path
    metadata: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "metadata", MappingProxyType(dict(self.metadata)))

    def sensor(self, channel: str) -> SensorInfo:
        for info in self.sensors:
            if info.channel == channel:
                return info
        raise KeyError(channel)

    def steps_of_kind(self, kind: str) -> list[StepData]:
        return [s for s in self.steps if s.step.kind == kind]
