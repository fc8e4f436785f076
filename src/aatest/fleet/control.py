"""Individuals / moving-range (I-MR) control charts with Western Electric run rules.

Each certified quantity of a model is a process: its values, in calibration order, are charted
with Shewhart's limits for individual observations (ISO 7870-2; Montgomery, *Introduction to
Statistical Quality Control*, §6.4). The process sigma is estimated from the mean moving range
of two, ``σ̂ = MR̄ / d₂`` with ``d₂ = 1.128``; the individuals' limits are ``x̄ ± 3σ̂`` and the
moving-range chart's upper limit is ``D₄·MR̄`` with ``D₄ = 3.267`` (its lower limit is 0).

A point is flagged by the rules of the Western Electric *Statistical Quality Control Handbook*
(1956) that need no subgrouping:

* ``rule 1``: one point beyond 3σ̂ of the centre line;
* ``rule 2``: two of three consecutive points beyond 2σ̂ on the same side;
* ``rule 4``: eight consecutive points on the same side of the centre line (a run: a shift);
* ``MR``: a moving range above its upper limit (a jump between consecutive calibrations).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

#: d₂ of a moving range of two (the mean range of two normal observations in σ)
D2 = 1.128
#: D₄ of a moving range of two: the moving-range chart's upper limit is D₄·MR̄
D4 = 3.267
#: control limits at ±3σ̂; the warning zone of rule 2 at ±2σ̂
LIMIT_SIGMAS, ZONE_A_SIGMAS = 3.0, 2.0
#: rule 2: two of three consecutive points; rule 4: eight in a row
RULE2_OF, RULE2_WINDOW, RULE4_RUN = 2, 3, 8
#: a moving range needs two points, its mean a second range
MIN_POINTS = 3

RULES = {
    "rule 1": "one point beyond 3σ of the centre line",
    "rule 2": "two of three consecutive points beyond 2σ on the same side",
    "rule 4": "eight consecutive points on the same side of the centre line",
    "MR": "moving range above D₄·MR̄",
}


@dataclass(frozen=True)
class Signal:
    """One flagged point: its index in the chart and the rule it broke."""

    index: int
    rule: str

    @property
    def description(self) -> str:
        return RULES[self.rule]


@dataclass(frozen=True)
class ControlChart:
    """An I-MR chart of one quantity of one group (a model, or a model on one rig)."""

    quantity: str
    model: str
    rig: str | None
    moments: tuple[datetime, ...]
    serials: tuple[str, ...]
    values: np.ndarray
    center: float
    mr_bar: float
    signals: tuple[Signal, ...]

    @property
    def sigma(self) -> float:
        return self.mr_bar / D2

    @property
    def limits(self) -> tuple[float, float]:
        return (self.center - LIMIT_SIGMAS * self.sigma, self.center + LIMIT_SIGMAS * self.sigma)

    @property
    def moving_ranges(self) -> np.ndarray:
        return np.abs(np.diff(self.values))

    @property
    def mr_ucl(self) -> float:
        return D4 * self.mr_bar

    def flagged(self) -> list[int]:
        """Indices of the points any rule flags, in order."""
        return sorted({s.index for s in self.signals})


def _rule1(z: np.ndarray) -> list[Signal]:
    return [Signal(int(i), "rule 1") for i in np.flatnonzero(np.abs(z) > LIMIT_SIGMAS)]


def _rule2(z: np.ndarray) -> list[Signal]:
    found: set[int] = set()
    if len(z) < RULE2_WINDOW:
        return []
    for side in (1.0, -1.0):
        beyond = side * z > ZONE_A_SIGMAS
        windows = sliding_window_view(beyond, RULE2_WINDOW)
        for start in np.flatnonzero(windows.sum(axis=1) >= RULE2_OF):
            found.update(int(start + k) for k in np.flatnonzero(windows[start]))
    return [Signal(i, "rule 2") for i in sorted(found)]


def _rule4(z: np.ndarray) -> list[Signal]:
    found: set[int] = set()
    if len(z) < RULE4_RUN:
        return []
    for side in (1.0, -1.0):
        run = sliding_window_view(side * z > 0, RULE4_RUN).all(axis=1)
        found.update(int(start + RULE4_RUN - 1) for start in np.flatnonzero(run))
    return [Signal(i, "rule 4") for i in sorted(found)]


def _mr_rule(moving: np.ndarray, ucl: float) -> list[Signal]:
    return [Signal(int(i) + 1, "MR") for i in np.flatnonzero(moving > ucl)]


def signals_of(values: np.ndarray, center: float, mr_bar: float) -> list[Signal]:
    """Every rule's flags of ``values`` about ``center`` with ``σ̂ = mr_bar / d₂``."""
    moving = np.abs(np.diff(values))
    if mr_bar <= 0:
        return []  # every value alike: nothing varies, nothing is out of control
    z = (values - center) / (mr_bar / D2)
    return [*_rule1(z), *_rule2(z), *_rule4(z), *_mr_rule(moving, D4 * mr_bar)]


def control_chart(quantity: str, model: str, rig: str | None, moments: Sequence[datetime],
                  serials: Sequence[str], values: Sequence[float]) -> ControlChart | None:
    """The I-MR chart of ``values`` (in calibration order); None below :data:`MIN_POINTS`."""
    x = np.asarray(values, dtype=float)
    if len(x) < MIN_POINTS:
        return None
    center, mr_bar = float(x.mean()), float(np.abs(np.diff(x)).mean())
    return ControlChart(quantity, model, rig, tuple(moments), tuple(serials), x, center,
                        mr_bar, tuple(signals_of(x, center, mr_bar)))
