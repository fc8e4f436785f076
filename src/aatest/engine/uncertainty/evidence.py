"""What the recorded data show about the budget's Type B components: motion and temperature.

The uncertainty stage reads the results; a few components are measured from the logs
themselves: the distortion of the table's motion (THD of the position log, harmonics 2–5 in
acceleration) and the servo's non-commanded content at the fundamental, and the temperature
logged beside the sensor during each record. One pass over the recording, vectorised (one
FFT per sine record); without a recording (a results.json re-read alone) the components are
reported as not evaluated.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

#: harmonics of the fundamental summed into the motion THD
HARMONICS = 5


@dataclass(frozen=True)
class MotionEvidence:
    """Distortion of one sine record's table motion, from the position log."""

    thd_accel: float
    """THD of the acceleration (harmonics 2..5 over the fundamental, k² weighted), ratio"""
    tracking_rel: float
    """|measured fundamental amplitude / commanded − 1| of the position, ratio"""


@dataclass(frozen=True)
class TemperatureEvidence:
    """Temperature logged beside the sensor during one record."""

    mean_c: float
    std_c: float


@dataclass(frozen=True)
class Evidence:
    """Per step id: the motion and temperature measured from the recording."""

    motion: dict[str, MotionEvidence] = field(default_factory=dict)
    temperature: dict[str, TemperatureEvidence] = field(default_factory=dict)
    recording: bool = False

    def temperature_over(self, step_ids: list[str] | None = None) -> TemperatureEvidence | None:
        """Mean and spread of the logged temperature over the given steps (all when None)."""
        ids = list(self.temperature) if step_ids is None else \
            [s for s in step_ids if s in self.temperature]
        if not ids:
            return None
        means = np.array([self.temperature[s].mean_c for s in ids])
        stds = np.array([self.temperature[s].std_c for s in ids])
        spread = float(np.sqrt(np.mean(stds**2) + np.var(means)))
        return TemperatureEvidence(float(np.mean(means)), spread)


def _motion(position_deg: np.ndarray, cycles: int, amplitude_deg: float) -> MotionEvidence | None:
    """THD and tracking of a coherent sine record (``cycles`` whole periods)."""
    n = position_deg.size
    if cycles < 1 or n < 4 * HARMONICS * cycles:
        return None
    spectrum = np.fft.rfft(position_deg - np.mean(position_deg))
    fundamental = abs(spectrum[cycles]) * 2.0 / n
    if fundamental <= 0:
        return None
    k = np.arange(2, HARMONICS + 1)
    harmonics = np.abs(spectrum[k * cycles]) * 2.0 / n
    thd = float(np.sqrt(np.sum((k**2 * harmonics) ** 2)) / fundamental)
    tracking = abs(fundamental / amplitude_deg - 1.0) if amplitude_deg else math.nan
    return MotionEvidence(thd, float(tracking))


def gather(data: Any) -> Evidence:
    """Measure the motion of every coherent sine record and the logged temperatures.

    Parameters
    ----------
    data
        The :class:`aatest.engine.dataset.Dataset` the analyses ran on (None: nothing measured).
    """
    if data is None:
        return Evidence()
    motion: dict[str, MotionEvidence] = {}
    temperature: dict[str, TemperatureEvidence] = {}
    present = data.metadata.get("temperature_present", True)
    for record in data.steps:
        step = record.step
        temps = record.daq.channels.get("temperature_c")
        if present and temps is not None and np.size(temps):
            temperature[step.id] = TemperatureEvidence(float(np.mean(temps)), float(np.std(temps)))
        if step.kind != "sine":
            continue
        position = record.table.channels.get(f"{step.axis}_position_deg")
        cycles = getattr(step, "cycles", None)
        amplitude = getattr(step, "amplitude_deg", None) or 0.0
        if position is not None and cycles:
            measured = _motion(np.asarray(position, dtype=float), int(cycles), float(amplitude))
            if measured is not None:
                motion[step.id] = measured
    return Evidence(motion, temperature, recording=True)
