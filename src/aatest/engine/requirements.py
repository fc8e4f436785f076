"""What an analysis needs from a plan, declared by the analysis and checked before motion.

An analysis plugin may declare ``requirements: ClassVar[tuple[Requirement, ...]]`` (what data
it needs, each checked against the expanded plan) and ``judges: ClassVar[tuple[str, ...]]``
(the acceptance quantities it produces). ``aatest validate`` and ``aatest run`` (before the
rig moves) check every listed analysis' requirements and refuse an unmet one at the
``FILE:LINE:COLUMN`` of the analysis entry or the step (exit 2); ``validate`` prints which
steps each analysis will use. A vendor's analysis without a declaration is not checked.
The same declarations generate the requirements table of docs/interfaces.md.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

from aatest.engine.steps import PlannedStep

#: a static position counts as "sensor axis up/down" above this |g| component (as the bias)
UP_G = 0.9


@dataclass(frozen=True)
class PlanView:
    """What a requirement is checked against: the planned steps, the rig and the sensors."""

    steps: tuple[PlannedStep, ...]
    chamber: str = "none"
    #: sensor channel → its axis on the table (``I``, ``O``, ``P``)
    sensor_axes: Mapping[str, str] = field(default_factory=dict)

    def recorded(self, kind: str | None = None) -> list[PlannedStep]:
        """The recorded steps, of one kind when ``kind`` is given."""
        return [s for s in self.steps if s.recorded and (kind is None or s.kind == kind)]


@dataclass(frozen=True)
class Check:
    """The outcome of one requirement: the step ids it uses, and what is missing if unmet.

    ``step_id`` names the step an unmet requirement points at (None: the analysis entry).
    """

    uses: tuple[str, ...] = ()
    problem: str | None = None
    step_id: str | None = None


@dataclass(frozen=True)
class Requirement:
    """One thing an analysis needs: ``need`` says it in words (docs, errors), ``check`` tests
    a plan against it."""

    need: str
    check: Callable[[PlanView], Check]


def steps_where(need: str, predicate: Callable[[PlannedStep], bool], minimum: int = 1,
                kind: str | None = None) -> Requirement:
    """At least ``minimum`` recorded steps (of ``kind``) for which ``predicate`` holds."""

    def check(view: PlanView) -> Check:
        found = tuple(s.id for s in view.recorded(kind) if predicate(s))
        if len(found) >= minimum:
            return Check(found)
        have = f"the plan has {len(found)}" if found else "the plan has none"
        return Check(found, f"needs {need}; {have}")

    return Requirement(need, check)


@dataclass(frozen=True)
class Unmet:
    """An unmet requirement of one analysis, with where to point at."""

    analysis: str
    message: str
    step_id: str | None


@dataclass(frozen=True)
class Coverage:
    """Per analysis: the steps it will use, and its unmet requirements."""

    uses: dict[str, tuple[str, ...]] = field(default_factory=dict)
    unmet: list[Unmet] = field(default_factory=list)


def requirements_of(cls: object) -> tuple[Requirement, ...] | None:
    """An analysis class' declared requirements, None when it declares none (not checked)."""
    declared = getattr(cls, "requirements", None)
    return tuple(declared) if declared is not None else None


def judges_of(cls: object) -> tuple[str, ...]:
    """The acceptance quantities an analysis class declares it produces (judged when listed)."""
    return tuple(getattr(cls, "judges", ()))


def produces_of(cls: object) -> Mapping[str, Requirement]:
    """What the plan must hold for each quantity an analysis class judges, where it declares
    it (``produces``: quantity → requirement; a quantity not named needs only the analysis'
    own ``requirements``)."""
    return dict(getattr(cls, "produces", {}))


def measures_of(cls: object) -> tuple[str, ...]:
    """Everything it can produce: ``judges`` and ``also_measures`` (measured when the data
    allow, judged when produced or asked for)."""
    return judges_of(cls) + tuple(getattr(cls, "also_measures", ()))


def check_plan(analyses: Mapping[str, object], view: PlanView) -> Coverage:
    """Check every analysis' declared requirements against a plan.

    ``analyses`` maps the procedure's analysis name to its plugin class.
    """
    coverage = Coverage()
    for name, cls in analyses.items():
        declared = requirements_of(cls)
        if declared is None:
            continue
        used: list[str] = []
        for requirement in declared:
            result = requirement.check(view)
            used += [s for s in result.uses if s not in used]
            if result.problem is not None:
                coverage.unmet.append(Unmet(name, result.problem, result.step_id))
        coverage.uses[name] = tuple(s.id for s in view.steps if s.id in used)
    return coverage


def needs_text(cls: object) -> str:
    """The declared needs of an analysis as one sentence (docs table, not-judged reasons)."""
    declared = requirements_of(cls)
    if declared is None:
        return "not declared"
    return "; ".join(r.need for r in declared) or "nothing"


def ids(steps: Sequence[PlannedStep]) -> tuple[str, ...]:
    """The ids of steps, in order."""
    return tuple(s.id for s in steps)
