"""Misalignment of a three-sensor unit from the pivoted test (docs/method.md §4.5).

Two estimators on the same recordings:

1. the published one (:mod:`misalignment_method`, contract §5) on the complex fundamentals of
   each sensor, referenced to the table's input fundamental so every step shares one phase;
2. our own: the full 3×3 sensitivity matrix S (sensor outputs = S · table-top acceleration) by
   least squares over all experiments and repetitions of a set. Each row divided by its main
   (complex) element leaves real direction ratios whose signs come from the phases; they are
   the tilt of each sensor's effective input axis towards its own x and y (internal
   misalignment and cross-axis sensitivity act alike). Original and pivoted sets separate the
   sensor's own part (flips with the pivot) from the mounting's (does not):
   sensor = (original − pivoted)/2, mounting = (original + pivoted)/2, with standard
   uncertainties from the scatter over repetitions.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np

from aatest.clocksync.freeze_pulse import SyncedStep
from aatest.engine.interfaces import AnalysisContext, AnalysisOutput, NoOptions
from aatest.engine.requirements import Requirement
from aatest.plugins.analysis import needs
from aatest.plugins.analysis._common import fundamental, select, steps_of
from aatest.plugins.analysis.misalignment_method import (
    AXIS_SENSOR,
    ORIGINAL_SETS,
    SCENARIOS,
    SENSOR_XY,
    evaluate,
    misalignment_from_spectra,
)
from aatest.recording.dataset import Dataset, SensorInfo
from aatest.results.misalignment import MisalignmentResult

__all__ = ["MisalignmentAnalysis", "misalignment_from_spectra"]

_TABLE_INDEX = {"P": 0, "O": 1, "I": 2}  # table-top coordinates (P, O, I)

#: sensor axes (P, O, I): a set's input directions must span all three
_AXES = 3


def input_direction(step: SyncedStep) -> np.ndarray:
    """Unit acceleration direction of the step in table-top (P, O, I) coordinates."""
    if step.step.axis == "inner":
        return np.array([0.0, 0.0, 1.0])
    logged = step.table.get("inner_position_deg")
    psi = np.radians(float(np.mean(logged)) if logged is not None else step.step.inner_deg)
    return np.array([np.sin(psi), np.cos(psi), 0.0])


def _responses(step: SyncedStep, sensors: list[SensorInfo]) -> tuple[complex, np.ndarray]:
    """(input fundamental °/s², sensor fundamentals V) of one misalignment step."""
    fs, f0 = step.sample_rate_hz, float(step.step.frequency_hz or 1.0)
    x = fundamental(np.asarray(step.table[f"{step.step.axis}_accel_dps2"]), f0, fs)
    y = np.array([fundamental(step.daq[s.channel], f0, fs) for s in sensors])
    return x, y


def _row_angles(row: np.ndarray, axis: str) -> np.ndarray:
    """Tilt (deg) of a sensor's effective axis towards its own x and y from a matrix row."""
    main = row[_TABLE_INDEX[axis]]
    x_ax, y_ax = SENSOR_XY[AXIS_SENSOR[axis]]
    ratios = np.real(row[[_TABLE_INDEX[x_ax], _TABLE_INDEX[y_ax]]] / main)
    return np.degrees(np.arctan(ratios))


def set_matrices(steps: Sequence[SyncedStep], sensors: list[SensorInfo]
                 ) -> dict[str, list[np.ndarray]]:
    """Per set: one complex 3×3 matrix S per repetition (outputs V per °/s² along P, O, I)."""
    by_set: dict[tuple[str, int], tuple[list[np.ndarray], list[np.ndarray]]] = defaultdict(
        lambda: ([], []))
    for s in steps:
        x, y = _responses(s, sensors)
        key = (str(s.step.mounting.scenario), s.step.repetition)
        by_set[key][0].append(input_direction(s) * x)
        by_set[key][1].append(y)
    out: dict[str, list[np.ndarray]] = defaultdict(list)
    for (set_name, _), (v_cols, y_cols) in sorted(by_set.items()):
        v, y = np.column_stack(v_cols), np.column_stack(y_cols)
        if np.linalg.matrix_rank(v) < _AXES:
            continue
        out[set_name].append(y @ np.linalg.pinv(v))
    return out


def _angles_by_set(mats: dict[str, list[np.ndarray]], sensors: list[SensorInfo]
                   ) -> dict[str, dict[str, np.ndarray]]:
    """Set → channel → (repetitions × 2) tilt angles in degrees."""
    return {set_name: {s.channel: np.array([_row_angles(m[i], s.axis) for m in ms])
                       for i, s in enumerate(sensors)} for set_name, ms in mats.items()}


def _mean_u(a: np.ndarray) -> tuple[list[float], list[float]]:
    n = a.shape[0]
    u = a.std(axis=0, ddof=1) / np.sqrt(n) if n > 1 else np.zeros(a.shape[1])
    return a.mean(axis=0).tolist(), u.tolist()


def matrix_estimates(angles: dict[str, dict[str, np.ndarray]], sensors: list[SensorInfo]
                     ) -> dict[str, Any]:
    """Sensor (pivot-flipping) and mounting parts per scenario with uncertainties."""
    result: dict[str, Any] = {}
    for key, (orig, piv) in SCENARIOS.items():
        if orig not in angles or piv not in angles:
            continue
        scen = {}
        for s in sensors:
            a, b = angles[orig][s.channel], angles[piv][s.channel]
            n = min(len(a), len(b))
            own, mount = 0.5 * (a[:n] - b[:n]), 0.5 * (a[:n] + b[:n])
            (ox, oy), (uox, uoy) = _mean_u(own)
            total = float(np.hypot(ox, oy))
            scen[s.channel] = {
                "sensor_tilt_x_deg": ox, "sensor_tilt_y_deg": oy, "u_sensor_tilt_deg": [uox, uoy],
                "sensor_angle_deg": total, "azimuth_deg": float(np.degrees(np.arctan2(oy, ox))),
                "mounting_tilt_deg": _mean_u(mount)[0], "u_mounting_tilt_deg": _mean_u(mount)[1],
                "repetitions": n,
            }
        result[key] = scen
    return result


def _spectra(mats: dict[str, list[np.ndarray]], sensors: list[SensorInfo]
             ) -> dict[tuple[str, str, str], complex]:
    """Mean matrices as the published method's inputs (responses per unit input)."""
    spectra = {}
    for set_name, ms in mats.items():
        mean = np.mean(ms, axis=0)
        for i, s in enumerate(sensors):
            for axis, j in _TABLE_INDEX.items():
                spectra[(set_name, axis, AXIS_SENSOR[s.axis])] = complex(mean[i, j])
    return spectra


class MisalignmentAnalysis:
    """Cross-axis ratios and misalignment of a three-sensor unit (published + matrix LS)."""

    key: ClassVar[str] = "misalignment"
    requires: ClassVar[tuple[str, ...]] = ("sync",)
    #: what the plan must hold (checked by ``validate``; aatest.engine.requirements)
    requirements: ClassVar[tuple[Requirement, ...]] = needs.MISALIGNMENT
    #: the acceptance quantities it produces (judged when it is listed)
    judges: ClassVar[tuple[str, ...]] = ("misalignment_deg", "cross_axis_ratio")
    Options: ClassVar[type[NoOptions]] = NoOptions
    Result: ClassVar[type[MisalignmentResult]] = MisalignmentResult

    def applies_to(self, data: Dataset) -> bool:
        axes = {s.axis for s in data.sensors}
        return axes >= {"I", "O", "P"} and any(
            p.mounting.scenario and p.kind == "sine" for p in data.planned)

    def run(self, data: Dataset, context: AnalysisContext) -> AnalysisOutput[MisalignmentResult]:
        sensors = sorted((s for s in data.sensors if s.axis in _TABLE_INDEX),
                         key=lambda s: _TABLE_INDEX[s.axis])[:3]
        steps = select(steps_of(context, "sine"), lambda p: bool(p.mounting.scenario))
        mats = set_matrices(steps, sensors)
        values = evaluate(_spectra(mats, sensors))
        values["matrix"] = {
            "scenarios": matrix_estimates(_angles_by_set(mats, sensors), sensors),
            "sets": {k: {"re": np.mean(m, axis=0).real.tolist(),
                         "im": np.mean(m, axis=0).imag.tolist(), "repetitions": len(m),
                         "pivoted": k not in ORIGINAL_SETS} for k, m in mats.items()},
            "columns": ["P", "O", "I"], "rows": [s.channel for s in sensors],
        }
        return AnalysisOutput(MisalignmentResult.model_validate(values))
