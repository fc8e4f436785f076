"""Where the table's motion and gravity point in a sensor's frame (docs/interfaces.md §4).

Frames: the sensors ride on the inner axis. A sensor on I sees inner-axis motion; outer-axis
motion at inner angle ψ lies along O·cos ψ + P·sin ψ of the table top, so a sensor on O sees
``cos ψ`` and one on P ``sin ψ`` of the outer acceleration. The analyses and their declared
data needs (:mod:`.needs`) both use these projections, so they live in a module of their own.
"""

from __future__ import annotations

import numpy as np

from aatest.engine.steps import PlannedStep


def axis_weights(sensor_axis: str, inner_deg: float | np.ndarray) -> dict[str, float | np.ndarray]:
    """Share of inner- and outer-axis acceleration along a sensor axis (I, O or P)."""
    psi = np.deg2rad(inner_deg)
    if sensor_axis == "I":
        return {"inner": 1.0, "outer": 0.0}
    if sensor_axis == "O":
        return {"inner": 0.0, "outer": np.cos(psi)}
    return {"inner": 0.0, "outer": np.sin(psi)}


def nominal_weight(step: PlannedStep, sensor_axis: str) -> float:
    """Projection of the step's moving axis onto the sensor axis at the commanded angles."""
    if step.axis not in ("inner", "outer"):
        return 0.0
    return float(axis_weights(sensor_axis, step.inner_deg)[step.axis])


def gravity_along_g(sensor_axis: str, inner_deg: float, outer_deg: float) -> float:
    """Specific force of gravity along a sensor axis (g) for a table at rest.

    Table-top frame (P, O, I): up = (−sin φ·cos ψ, sin φ·sin ψ, cos φ) for outer φ, inner ψ.
    """
    psi, phi = np.radians(inner_deg), np.radians(outer_deg)
    up = {"P": -np.sin(phi) * np.cos(psi), "O": np.sin(phi) * np.sin(psi), "I": np.cos(phi)}
    return float(up[sensor_axis])
