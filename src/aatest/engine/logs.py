"""Sampled logs: what one logger (table controller or sensor DAQ) recorded during one step.

Arrays are made read-only on construction: records are created by the engine (or an importer)
and only read afterwards.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

TABLE = "table"
DAQ = "daq"

#: Channels a table log carries (controller estimates per axis, raw feedback, freeze pulse).
TABLE_CHANNELS: dict[str, str] = {
    "inner_position_deg": "deg",
    "inner_rate_dps": "deg/s",
    "inner_accel_dps2": "deg/s^2",
    "outer_position_deg": "deg",
    "outer_rate_dps": "deg/s",
    "outer_accel_dps2": "deg/s^2",
    "inner_feedback_deg": "deg",
    "outer_feedback_deg": "deg",
    "sync_pulse": "1",
    "fp_latch_s": "s",
}

#: Channels every DAQ log carries besides its sensor voltages (``v_*``, volts).
DAQ_AUX_CHANNELS: dict[str, str] = {"sync_pulse": "1", "trigger": "1", "temperature_c": "degC"}


@dataclass(frozen=True)
class SampledLog:
    """Samples of one logger on its own clock.

    Parameters
    ----------
    source
        ``"table"`` or ``"daq"``.
    sample_rate_hz
        Nominal sample rate of the logger's clock.
    time_s
        Time stamps in seconds on the logger's own clock (not synchronised).
    channels
        Channel name → 1-D array, each the same length as ``time_s``.
    units
        Channel name → unit string.
    quantisation
        Optional channel name (or ``"time_s"``) → ``(quantum, offset)`` when the logger produces
        integer codes: every value is ``code·quantum + offset`` in float64 (an ADC: one LSB in V
        and the range's low end; an encoder: its resolution in degrees and 0). The recording
        stores such channels as their codes where that is bit-exact (docs/interfaces.md §2).
    """

    source: str
    sample_rate_hz: float
    time_s: np.ndarray
    channels: Mapping[str, np.ndarray]
    units: Mapping[str, str] = field(default_factory=dict)
    quantisation: Mapping[str, tuple[float, float]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        time = np.asarray(self.time_s, dtype=np.float64)
        frozen: dict[str, np.ndarray] = {}
        for name, values in self.channels.items():
            arr = np.asarray(values)
            if arr.shape != time.shape:
                raise ValueError(
                    f"{self.source} channel {name!r} has {arr.shape} samples, time has {time.shape}"
                )
            arr = arr.copy() if arr.flags.writeable else arr
            arr.flags.writeable = False
            frozen[name] = arr
        time = time.copy() if time.flags.writeable else time  # read-only: kept, as channels
        time.flags.writeable = False
        object.__setattr__(self, "time_s", time)
        object.__setattr__(self, "channels", MappingProxyType(frozen))
        object.__setattr__(self, "units", MappingProxyType(dict(self.units)))
        quanta = {str(k): (float(q), float(o)) for k, (q, o) in self.quantisation.items()}
        object.__setattr__(self, "quantisation", MappingProxyType(quanta))

    def __len__(self) -> int:
        return int(self.time_s.shape[0])

    def __getitem__(self, name: str) -> np.ndarray:
        return self.channels[name]

    def sensor_channels(self) -> list[str]:
        """Sensor voltage channels, by the ``v_`` naming convention."""
        return [c for c in self.channels if c.startswith("v_")]
