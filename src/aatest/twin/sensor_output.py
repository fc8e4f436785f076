"""The sensor's output stage after its dynamics, formed in place.

The terms :func:`aatest.twin.sensor.output_volts` adds after the sensor dynamics. Each function
performs the same IEEE operations on the same operands as the plain expression in its
docstring (x² is x·x, a·b and a + b commute bit for bit), in one or two buffers instead of a
new array per operation: the output stage runs on every channel of every generation block,
and each fresh full-length array costs page faults on top of its pass.
"""

from __future__ import annotations

import numpy as np

from aatest.twin.model import SensorModel


def cubic(alpha: np.ndarray, c3: float, range_dps2: float) -> np.ndarray:
    """α·(1 + c3·(α/range)²) in a new array: the same operations in one buffer (x² is x·x,
    a·b and a + b commute bit for bit)."""
    out = np.divide(alpha, range_dps2)
    np.square(out, out=out)
    out *= c3
    out += 1.0
    out *= alpha
    return out


def volts_before_drift(model: SensorModel, alpha: np.ndarray, d_temp: np.ndarray) -> np.ndarray:
    """bias + scale(T)·α + bias_temperature·ΔT (V), a new array, in place where it can be."""
    if d_temp.dtype != np.float64 or alpha.dtype != np.float64:  # the plain formula
        scale = model.scale_v_per_dps2 if model.scale_temperature is None else (
            model.scale_v_per_dps2 * (1.0 + model.scale_temperature.coefficient_per_c * d_temp))
        plain = model.bias_v + scale * alpha
        if model.bias_temperature is not None:
            plain = plain + model.bias_temperature.coefficient_v_per_c * d_temp
        return np.asarray(plain, dtype=np.float64)
    if model.scale_temperature is not None:  # scale·(1 + coefficient·ΔT) per sample
        volts = np.multiply(d_temp, model.scale_temperature.coefficient_per_c)
        volts += 1.0
        volts *= model.scale_v_per_dps2
        volts *= alpha
    else:
        volts = np.multiply(alpha, model.scale_v_per_dps2)
    volts += model.bias_v
    if model.bias_temperature is not None:
        volts += np.multiply(d_temp, model.bias_temperature.coefficient_v_per_c)
    return volts


def jerk_volts(model: SensorModel, sensed: np.ndarray, response: np.ndarray, dt_s: float
               ) -> np.ndarray | float:
    """The jerk terms (V): ``jerk_sensitivity`` on the sensed acceleration's jerk, and
    ``jerk_distortion`` on the squared jerk of the rotor's response (after the dynamics)."""
    out: np.ndarray | float = 0.0
    if model.jerk_sensitivity is not None:
        out = gradient(sensed, dt_s)
        out *= model.jerk_sensitivity.coefficient_v_per_dps3
    if model.jerk_distortion is not None:
        squared = gradient(response, dt_s)
        np.square(squared, out=squared)
        squared *= model.jerk_distortion.coefficient_v_per_dps3_squared
        out = np.add(out, squared, out=squared)  # (0.0 + x where no jerk_sensitivity)
    return out


def gradient(x: np.ndarray, dx: float) -> np.ndarray:
    """``np.gradient(x, dx)`` of a 1-D float64 record: the same central differences
    (x[k+1] − x[k−1])/(2·dx) and one-sided ends, without its two full-length temporaries."""
    if x.ndim != 1 or x.dtype != np.float64 or x.size < 2:  # noqa: PLR2004 - two samples
        return np.asarray(np.gradient(x, dx))
    out = np.empty_like(x)
    np.subtract(x[2:], x[:-2], out=out[1:-1])
    out[1:-1] /= 2.0 * dx
    out[0] = (x[1] - x[0]) / dx
    out[-1] = (x[-1] - x[-2]) / dx
    return out
