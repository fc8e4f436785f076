"""Fleet diagnosis: does a discrepancy effect belong to a rig or to one unit?

``aatest diagnose`` names the effects a recording shows that the nominal model lacks (a
misaligned axis, a logger gain error, a table wobble…). One unit showing an effect says little
about where it comes from; the same effect in most units calibrated on one rig, and not in the
same models on other rigs, points at the rig. Per rig, every effect is counted over the units
diagnosed there:

* **rig effect** — shown by at least :data:`MIN_UNITS_FOR_RIG` units and by at least
  :data:`RIG_SHARE` of the units diagnosed on that rig;
* **unit effect** — shown by fewer (one unit, or a minority of the rig's units);
* **undecided** — the rig has only one diagnosed unit: rig and unit cannot be told apart.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass

#: the share of a rig's diagnosed units that must show an effect for it to be the rig's
RIG_SHARE = 0.5
#: and at least this many units (one unit never makes a pattern)
MIN_UNITS_FOR_RIG = 2

RIG, UNIT, UNDECIDED = "rig effect", "unit effect", "undecided"


@dataclass(frozen=True)
class UnitDiagnosis:
    """The effects one diagnosis of one unit on one rig named (``None``: not diagnosed)."""

    serial: str
    model: str
    rig: str
    effects: frozenset[str] | None
    source: str


@dataclass(frozen=True)
class EffectRecurrence:
    """One effect on one rig: which of the rig's diagnosed units show it, and the verdict."""

    rig: str
    effect: str
    units: tuple[str, ...]
    diagnosed: int
    classification: str

    @property
    def share(self) -> float:
        return len(self.units) / self.diagnosed


@dataclass(frozen=True)
class RigSummary:
    """A rig's diagnosed and undiagnosed units and its effects, most frequent first."""

    rig: str
    diagnosed: tuple[str, ...]
    undiagnosed: tuple[str, ...]
    effects: tuple[EffectRecurrence, ...]


def classify(units_showing: int, diagnosed: int) -> str:
    """The verdict on an effect ``units_showing`` of the rig's ``diagnosed`` units show."""
    if diagnosed < MIN_UNITS_FOR_RIG:
        return UNDECIDED
    if units_showing >= MIN_UNITS_FOR_RIG and units_showing / diagnosed >= RIG_SHARE:
        return RIG
    return UNIT


def _per_unit(diagnoses: Sequence[UnitDiagnosis]) -> dict[str, dict[str, set[str] | None]]:
    """Per rig, per serial: the union of the effects of its diagnoses (None: none readable)."""
    rigs: dict[str, dict[str, set[str] | None]] = defaultdict(dict)
    for d in diagnoses:
        known = rigs[d.rig].get(d.serial)
        if d.effects is None:
            rigs[d.rig].setdefault(d.serial, None)
        else:
            rigs[d.rig][d.serial] = (known or set()) | set(d.effects)
    return rigs


def summarise(diagnoses: Sequence[UnitDiagnosis]) -> list[RigSummary]:
    """The recurrence of every effect on every rig, rigs in name order."""
    out = []
    for rig, units in sorted(_per_unit(diagnoses).items()):
        diagnosed = sorted(s for s, e in units.items() if e is not None)
        showing: dict[str, list[str]] = defaultdict(list)
        for serial in diagnosed:
            for effect in units[serial] or ():
                showing[effect].append(serial)
        effects = sorted((EffectRecurrence(rig, effect, tuple(serials), len(diagnosed),
                                           classify(len(serials), len(diagnosed)))
                          for effect, serials in showing.items()),
                         key=lambda e: (-len(e.units), e.effect))
        out.append(RigSummary(rig, tuple(diagnosed),
                              tuple(sorted(s for s, e in units.items() if e is None)),
                              tuple(effects)))
    return out
