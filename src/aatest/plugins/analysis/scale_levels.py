"""Scale factor per acceleration level and set-point, and the linearity across the levels.

The candidates of a sensor (:func:`.scale_factor.calibration_candidates`: sine along its axis
at the frequency nearest 1 Hz) are grouped by peak acceleration and chamber set-point; each
group is calibrated on its own (:func:`.scale_factor.sensor_levels`), so a procedure with
100, 250 and 400 °/s² gets three scale factors, none silently dropped. The headline — the
channel's ``scale_v_per_dps2`` — is the largest level at the set-point nearest 25 °C (the
1 Hz, 70 %-of-range test of docs/method.md §4.3) and names its level and set-point. With two
or more levels at that set-point the linearity across them is measured
(:class:`aatest.results.scale_factor.LevelLinearity`). The calibration itself is the scale-factor
analysis's; this module only groups, chooses and compares, so it imports nothing of it.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence
from typing import Any

import numpy as np

from aatest.clocksync.freeze_pulse import SyncedStep

#: the reference temperature the headline scale factor is stated at, °C
T_REF_C = 25.0
#: two levels closer than this relative difference are the same level
_SAME_LEVEL = 1e-3
#: levels a linearity needs
MIN_LEVELS = 2

Level = tuple[float, float | None]


def level_groups(candidates: Sequence[SyncedStep]) -> dict[Level, list[SyncedStep]]:
    """(peak acceleration °/s², set-point °C or None) → its records, in ascending order.

    ``candidates``: a sensor's calibration records (:func:`.scale_factor.calibration_candidates`).
    """
    groups: dict[Level, list[SyncedStep]] = defaultdict(list)
    for s in candidates:
        accel = float(s.step.accel_dps2 or 0.0)
        same = next((a for a, t in groups if t == s.step.temperature_c
                     and abs(a - accel) <= _SAME_LEVEL * max(a, accel)), accel)
        groups[(same, s.step.temperature_c)].append(s)
    return dict(sorted(groups.items(), key=lambda kv: (kv[0][1] or 0.0, kv[0][0])))


def headline_level(levels: Sequence[Level]) -> Level:
    """The largest level at the set-point nearest 25 °C (no set-point counts as 25 °C)."""
    def distance(t: float | None) -> float:
        return 0.0 if t is None else abs(t - T_REF_C)

    nearest = min(distance(t) for _a, t in levels)
    return max((lv for lv in levels if distance(lv[1]) == nearest), key=lambda lv: lv[0])


def linearity(levels: dict[Level, dict[str, Any]], temperature_c: float | None,
              range_dps2: float) -> dict[str, Any] | None:
    """The levels' responses against the best line through the origin (≥ 2 levels)."""
    at = sorted((a, r["scale_v_per_dps2"]) for (a, t), r in levels.items() if t == temperature_c)
    if len(at) < MIN_LEVELS:
        return None
    accel = np.array([a for a, _k in at])
    scale = np.array([k for _a, k in at])
    response = scale * accel  # V at each level's peak acceleration
    k_line = float(response @ accel / (accel @ accel))
    deviation = (response - k_line * accel) / k_line
    return {"accel_dps2": accel.tolist(), "scale_v_per_dps2": scale.tolist(),
            "scale_v_per_dps2_line": k_line, "deviation_dps2": deviation.tolist(),
            "nonlinearity_pct_fr": float(100.0 * np.max(np.abs(deviation)) / (2 * range_dps2)),
            "temperature_c": temperature_c}
