"""The record of one simulated step: what the World knows when the DAQ starts
(:class:`StepSetup`), and what synthesis hands back (:class:`SimulatedStep`, whose
:class:`LazyTruth` computes its expensive entries on first access).

A module of its own so the synthesis stages (:mod:`aatest.twin.synthesis`,
:mod:`aatest.twin.rigid_motion`, :mod:`aatest.twin.table_log`) share these records without
importing one another.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from aatest.engine.logs import SampledLog
from aatest.engine.steps import PlannedStep
from aatest.twin import kinematics as kin
from aatest.twin.chamber import ThermalState
from aatest.twin.clocks import DaqClock
from aatest.twin.model import RigModel
from aatest.twin.table import AxisTruth


@dataclass(frozen=True)
class StepSetup:
    """Everything the World knows about one recorded step when the DAQ starts."""

    model: RigModel
    step: PlannedStep
    inner: AxisTruth
    outer: AxisTruth
    clock: DaqClock
    thermal: ThermalState
    #: channel → sensor axes (columns x, y, z) in table-top coordinates
    axes: dict[str, np.ndarray]
    stop_lag_s: float

    @property
    def gimbal(self) -> kin.GimbalErrors:
        return kin.GimbalErrors(self.model.table.orthogonality_arcsec,
                                self.model.table.wobble_arcsec)

    @property
    def trigger_index(self) -> int:
        return round(self.model.daq.start_lead_s * self.clock.sample_rate_hz)

    @property
    def trigger_time_s(self) -> float:
        """Lab time of the trigger = first table log sample."""
        return float(self.clock.lab_time(self.trigger_index / self.clock.sample_rate_hz))


class LazyTruth(Mapping[str, Any]):
    """The truth of a step; expensive entries (noise-free volts, undelayed sensor-axis
    acceleration) are computed on first access, so plugins that never look pay nothing.

    Deferred computations receive the mapping as their argument instead of closing over it:
    a closure cycle would keep whole records alive until a full garbage collection.
    """

    def __init__(self, **values: Any) -> None:
        self._values: dict[str, Any] = dict(values)
        self._deferred: dict[str, Callable[[LazyTruth], Any]] = {}

    def defer(self, key: str, compute: Callable[[LazyTruth], Any]) -> None:
        self._deferred[key] = compute

    def __setitem__(self, key: str, value: Any) -> None:
        self._values[key] = value

    def update(self, other: Mapping[str, Any]) -> None:
        self._values.update(other)

    def __getitem__(self, key: str) -> Any:
        if key not in self._values and key in self._deferred:
            self._values[key] = self._deferred.pop(key)(self)
        return self._values[key]

    def __iter__(self) -> Iterator[str]:
        yield from list(self._values) + [k for k in self._deferred if k not in self._values]

    def __len__(self) -> int:
        return len(set(self._values) | set(self._deferred))


@dataclass(frozen=True)
class SimulatedStep:
    """Both logs of one step and the truth behind them (see :func:`synthesise`)."""

    table: SampledLog
    daq: SampledLog
    truth: LazyTruth


def read_only(channels: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Hand fresh arrays to the (immutable) log without the defensive copy it makes of
    writeable ones; nothing else holds them for writing."""
    for values in channels.values():
        values.flags.writeable = False
    return channels
