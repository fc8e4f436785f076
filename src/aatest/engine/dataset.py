"""The one input every analysis reads: steps with their two raw logs and the sensors' nominals.

A :class:`Dataset` is built either from an aatest recording (``recording.mcap``) or from a
measured-data import directory (docs/interfaces.md §3), so analyses and ``diagnose`` never care
where the data came from and can always be re-run offline. Its per-channel sensor record,
:class:`SensorInfo`, is defined with the datasheet it comes from in
:mod:`aatest.engine.datasheet` and re-exported here.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

from aatest.engine.datasheet import SensorAxis, SensorInfo
from aatest.engine.logs import SampledLog
from aatest.engine.steps import PlannedStep

__all__ = ["Dataset", "SensorAxis", "SensorInfo", "StepData"]


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
