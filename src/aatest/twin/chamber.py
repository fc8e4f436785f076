"""Temperature chamber: set-point steps and the sensor's first-order thermal lag.

The chamber air follows a set-point step quickly compared with the sensor, so the air is taken
to jump to the set-point and the sensor to follow with time constant τ:
T(t) = T_set + (T_from − T_set)·exp(−(t − t_step)/τ). Stabilisation = the soak time has
elapsed *and* the sensor is within the stable band of the set-point (docs/method.md §4.2).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aatest.twin.model import ChamberModel


@dataclass
class ThermalState:
    """Sensor temperature history as one exponential segment since the last set-point step."""

    model: ChamberModel
    setpoint_c: float
    from_c: float
    step_time_s: float = 0.0

    @classmethod
    def ambient(cls, model: ChamberModel, temperature_c: float | None = None) -> ThermalState:
        t = model.ambient_c if temperature_c is None else temperature_c
        return cls(model=model, setpoint_c=t, from_c=t)

    def temperature_at(self, lab_time_s: np.ndarray | float) -> np.ndarray:
        """Sensor temperature (°C) at lab times (not before the last step).

        Settled (``from_c`` is the set-point), at finite times: the set-point + (+0)·decay with
        0 ≤ decay ≤ 1 is the set-point + 0.0 at every time, bit for bit, without the five
        passes of the decay (the stepped-sine procedure runs at ambient throughout).
        """
        times = np.asarray(lab_time_s, dtype=float)
        if (self.from_c == self.setpoint_c and self.model.sensor_time_constant_s > 0.0
                and times.ndim >= 1 and np.isfinite([self.setpoint_c, self.step_time_s]).all()
                and np.isfinite(times).all()):
            return np.full(times.shape, self.setpoint_c + 0.0)
        elapsed = np.maximum(times - self.step_time_s, 0.0)
        decay = np.exp(-elapsed / self.model.sensor_time_constant_s)
        return self.setpoint_c + (self.from_c - self.setpoint_c) * decay

    def set_point(self, setpoint_c: float, lab_time_s: float) -> None:
        """Step the chamber to a new set-point at ``lab_time_s``."""
        self.from_c = float(self.temperature_at(lab_time_s))
        self.setpoint_c = float(setpoint_c)
        self.step_time_s = float(lab_time_s)

    def time_to_stable_s(self, lab_time_s: float, soak_s: float) -> float:
        """Lab seconds from ``lab_time_s`` until soak has elapsed and the sensor is in band."""
        gap = abs(float(self.temperature_at(lab_time_s)) - self.setpoint_c)
        band = self.model.stable_band_c
        needed = 0.0 if gap <= band else self.model.sensor_time_constant_s * np.log(gap / band)
        return max(float(soak_s), needed)

    def time_to_spread_s(self, tolerance_c: float, window_s: float) -> tuple[float, float]:
        """Seconds after the set-point step at which the sensor temperature's spread over the
        trailing ``window_s`` is first ≤ ``tolerance_c``, and that spread (°C).

        The sensor follows one exponential since the step, so the spread over [t − w, t] is
        |T(t − w) − T(t)| = |ΔT₀|·e^(−(t − w)/τ)·(1 − e^(−w/τ)), solved here for t ≥ w.
        """
        tau = self.model.sensor_time_constant_s
        first = abs(self.from_c - self.setpoint_c) * -np.expm1(-window_s / tau)  # spread at t = w
        extra = 0.0 if first <= tolerance_c else tau * float(np.log(first / tolerance_c))
        return window_s + extra, first * float(np.exp(-extra / tau))
