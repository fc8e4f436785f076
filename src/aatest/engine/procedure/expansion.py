"""A plan with where each step came from: the planner's expansion, kept per plan.

The planner (:mod:`.planner`) records, for every plan it expands in this process, which YAML
entry produced each step and which sweep points it dropped; the envelope check
(:func:`.envelope.check_envelope`) reads the step sources back by plan (:func:`trace_of`) to
point at file positions. Both import this module; neither imports the other for it.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from aatest.engine.steps import Plan

#: a path into the procedure YAML, e.g. ("steps", 2, "sine_sweep")
YamlPath = tuple[str | int, ...]


@dataclass(frozen=True)
class SkippedPoint:
    """A sweep point dropped because it lies outside the envelope."""

    label: str
    source: YamlPath
    frequency_hz: float
    amplitude_deg: float
    accel_dps2: float
    group: str
    reasons: tuple[str, ...]
    limits: tuple[str, ...] = ()

    def describe(self) -> str:
        """The reasons, each with the limit it breaks: ``message [limit]; ...``."""
        return "; ".join(f"{r} [{lim}]" for r, lim in zip(self.reasons, self.limits, strict=True))

    def to_json(self) -> dict[str, Any]:
        """Return the point as the JSON object of the plan's skipped list."""
        return {"label": self.label, "frequency_hz": self.frequency_hz,
                "amplitude_deg": self.amplitude_deg, "accel_dps2": self.accel_dps2,
                "group": self.group, "reasons": list(self.reasons), "limits": list(self.limits)}


@dataclass(frozen=True)
class Expansion:
    """A plan plus where each step came from and what was skipped."""

    plan: Plan
    sources: Mapping[str, YamlPath]
    skipped: tuple[SkippedPoint, ...] = ()
    #: (step id, requested Hz, planned Hz) of every frequency moved to whole cycles
    snapped: tuple[tuple[str, float, float], ...] = ()

    def to_contract_json(self) -> dict[str, Any]:
        """The ``plan --json`` document with the extra key ``skipped``."""
        return {**self.plan.to_contract_json(), "skipped": [s.to_json() for s in self.skipped]}

    def snapped_lines(self) -> list[str]:
        """What ``validate`` prints about frequencies moved to whole cycles (snap: coherent)."""
        return [f"snapped: {step}: {asked:g} Hz → {planned:.6g} Hz (whole cycles in the record; "
                "snap: none keeps the frequency asked)" for step, asked, planned in self.snapped]

    def skipped_lines(self) -> list[str]:
        """What ``validate`` prints about dropped points: a count, then one line per point."""
        if not self.skipped:
            return []
        head = (f"skipped {len(self.skipped)} point(s) outside the envelope "
                "(skip_outside_envelope: true):")
        return [head, *(f"  {s.label}: {s.describe()}" for s in self.skipped)]


_TRACES: OrderedDict[Plan, Expansion] = OrderedDict()
_TRACE_KEEP = 32


def trace_of(plan: Plan) -> Expansion | None:
    """The :class:`Expansion` of a plan made by :func:`~.planner.expand` in this process, if
    known."""
    return _TRACES.get(plan)


def remember(expansion: Expansion) -> None:
    """Keep ``expansion`` for :func:`trace_of` (the most recent few plans)."""
    _TRACES[expansion.plan] = expansion
    while len(_TRACES) > _TRACE_KEEP:
        _TRACES.popitem(last=False)
