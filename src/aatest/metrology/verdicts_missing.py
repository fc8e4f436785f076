"""Not measured is never passed: the quantities a procedure asked for and did not get.

A quantity is *asked* when the procedure lists it in ``acceptance.judge``, or (without that
list) when the procedure sets its limit or a listed analysis declares it produces it
(``judges``, :mod:`aatest.engine.requirements`) — then its limit comes from the datasheet.
Each asked quantity without a value becomes a ``not judged`` verdict with the reason (which
analysis did not apply, failed or produced nothing, and what it needs); so does an analysis
the procedure lists that did not apply to the data. The overall verdict is then
``incomplete`` (contracts §6 "Verdicts"). An asked quantity that no listed analysis can produce
is known before the run (:func:`unproduced`): the preflight refuses it, so here it is met only
when an older run is analysed again.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from aatest.engine.errors import Problem
from aatest.engine.interfaces import SensorDatasheet
from aatest.engine.procedure.models import Acceptance
from aatest.engine.requirements import PlanView, judges_of, measures_of, needs_text, produces_of
from aatest.metrology.verdicts_limits import JUDGED, QUANTITY_UNITS, limits
from aatest.positioned_yaml import locate
from aatest.results import RunResults
from aatest.results.base import Verdict

log = logging.getLogger("aatest.verdicts")

#: quantities judged per sensor of a misalignment unit (labels, not channels)
PER_SENSOR = frozenset({"misalignment_deg", "cross_axis_ratio"})
#: why a quantity can be absent although its analysis ran
NOT_RESOLVED = {
    "nonlinearity_pct_fr": "one acceleration level: no non-linearity is resolved (a fit's "
    "deviation from itself is 0 by construction, whatever its order); record two or more levels "
    "(e.g. accelerations_dps2: [100, 250, 400]) to measure the linearity across them",
}
#: the channel a verdict names when it is about the whole unit
ALL = "all"


@dataclass(frozen=True)
class Listed:
    """An analysis the procedure lists: its plugin name, result key and class."""

    name: str
    key: str
    cls: Any


def asked(acceptance: Acceptance, listed: Sequence[Listed]) -> list[str]:
    """The quantities the procedure asks to be judged, in the order of ``JUDGED``."""
    wanted: set[str]
    if acceptance.judge is not None:
        wanted = set(acceptance.judge)
    else:
        wanted = set(acceptance.limits.model_dump(exclude_none=True))
        wanted |= {q for item in listed for q in judges_of(item.cls)}
    return [q for q in JUDGED if q in wanted]


def unproduced(acceptance: Acceptance, listed: Sequence[Listed]) -> list[str]:
    """The asked quantities (:func:`asked`) that no listed analysis can produce: known from
    the procedure alone, so ``validate`` refuses them before anything moves
    (:func:`aatest.engine.analysis.coverage.check_coverage`)."""
    return [q for q in asked(acceptance, listed)
            if not any(q in measures_of(item.cls) for item in listed)]


def acceptance_problems(proc: Any, listed: Sequence[Listed],
                        installed: Callable[[], Sequence[Listed]], filename: str,
                        view: PlanView | None = None,
                        entries: Mapping[str, int] | None = None) -> list[Problem]:
    """Each asked quantity of procedure ``proc`` that its listed analyses cannot produce on
    the plan ``view``: none of them produces it, or each that does declares what the plan
    must hold for it (``produces``) and the plan does not. The run could only end
    ``incomplete``, so the plan check (:func:`aatest.engine.analysis.coverage.check_coverage`)
    refuses it before anything moves, at its ``acceptance`` entry (at the producing analysis'
    entry when only the default judging asks for it). ``installed`` gives every installed
    analysis (asked only when one is missing); ``entries`` the index of the ``analysis:``
    entry of each listed plugin."""
    missing = unproduced(proc.acceptance, listed)
    everything = installed() if missing else []
    problems = [_asked_problem(proc, filename, q, no_producer(q, listed, everything),
                               any(q in measures_of(item.cls) for item in everything))
                for q in missing]
    if view is None:
        return problems
    for quantity in asked(proc.acceptance, listed):
        producers = [item for item in listed if quantity in measures_of(item.cls)]
        unmet = [(item, need.need, found.problem) for item in producers
                 if (need := produces_of(item.cls).get(quantity)) is not None
                 and (found := need.check(view)).problem is not None]
        if producers and len(unmet) == len(producers):
            item, need_text, problem = unmet[0]
            why = (f"analysis '{item.name}' produces it only from {need_text}: "
                   f"{str(problem).removeprefix(f'needs {need_text}; ')}")
            index = (entries or {}).get(item.name, 0)
            problems.append(_asked_problem(proc, filename, quantity, why, True, index))
    return problems


def _asked_problem(proc: Any, filename: str, quantity: str, why: str, can: bool,
                   producer: int | None = None) -> Problem:
    """The located problem of an asked quantity the run cannot give (``why``): at its
    ``acceptance`` entry, else at the producing analysis' entry (index ``producer``:
    asked by default)."""
    judge = proc.acceptance.judge
    limited = proc.acceptance.limits.model_dump(exclude_none=True)
    if judge is not None:
        path: tuple[Any, ...] = ("acceptance", "judge", judge.index(quantity))
        asks, fix = f"acceptance.judge asks for {quantity}", "leave it out of acceptance.judge"
    elif quantity in limited or producer is None:
        path = ("acceptance", "limits", quantity)
        asks = f"a limit is set for {quantity} (judged, as acceptance.judge is not given)"
        fix = "name the quantities to judge in acceptance.judge"
    else:
        path = ("analysis", producer)
        asks = f"{quantity} is judged (a listed analysis produces it, acceptance.judge is unset)"
        fix = "name the quantities to judge in acceptance.judge"
    line, col = locate(proc.source_tree, path) if proc.source_tree else (1, 1)
    add = ("list that analysis under analysis, or " if producer is None else
           "add what it needs to the plan, or ") if can else ""
    return Problem(filename, line, col, ".".join(map(str, path)),
                   f"{asks}, but {why}. The run could only end incomplete: {add}{fix}")


def no_producer(quantity: str, listed: Sequence[Listed], installed: Sequence[Listed]) -> str:
    """Why no listed analysis gives ``quantity``, naming an installed one that would: the one
    wording of ``validate``'s refusal and of a ``not judged`` verdict's reason."""
    names = ", ".join(item.name for item in listed) or "none"
    hint = next((f"; the analysis '{item.name}' does" for item in installed
                 if quantity in measures_of(item.cls)), "")
    return f"no listed analysis produces it (listed: {names}){hint}"


def _reason(quantity: str, channel: str, results: RunResults, listed: Sequence[Listed],
            installed: Sequence[Listed]) -> str:
    """Why ``quantity`` has no value: the producing analysis' state and what it needs."""
    producer = next((item for item in listed if quantity in measures_of(item.cls)), None)
    if producer is None:
        return no_producer(quantity, listed, installed)
    needs = needs_text(producer.cls)
    if producer.name in results.analysis_errors:
        return f"analysis '{producer.name}' failed: {results.analysis_errors[producer.name]}"
    if producer.name in results.analysis_skipped:
        return f"analysis '{producer.name}' does not apply to this data; it needs {needs}"
    where = "" if channel == ALL else f" for {channel}"
    return (f"analysis '{producer.name}' produced no value{where}; "
            f"{NOT_RESOLVED.get(quantity, f'it needs {needs}')}")


def missing(results: RunResults, judged: Sequence[Verdict],
            sheets: Mapping[str, SensorDatasheet], acceptance: Acceptance,
            listed: Sequence[Listed], installed: Sequence[Listed] = ()) -> list[Verdict]:
    """A ``not judged`` verdict per asked quantity without a value, and per listed analysis
    that did not apply (when no other verdict already names it). ``installed`` (every
    installed analysis, found by the engine) lets a reason name the analysis that would
    produce a quantity nobody listed."""
    have = {(v.quantity, v.channel) for v in judged}
    have_any = {v.quantity for v in judged}
    out: list[Verdict] = []
    first = next(iter(sheets.values()), None)
    for quantity in asked(acceptance, listed):
        if quantity in PER_SENSOR:
            todo = [] if quantity in have_any or first is None else [(ALL, first)]
        else:
            todo = [(ch, sheet) for ch, sheet in sheets.items() if (quantity, ch) not in have]
        for channel, sheet in todo:
            limit, source = limit_of(quantity, sheet, acceptance)
            out.append(Verdict(
                quantity=quantity, channel=channel, value=None, limit=limit,
                rule=acceptance.rule, verdict="not judged", unit=QUANTITY_UNITS[quantity],
                limit_source=source, reason=_reason(quantity, channel, results, listed,
                                                    installed)))
    cited = " ".join(v.reason for v in out)
    for item in listed:
        if item.name in results.analysis_skipped and f"'{item.name}'" not in cited:
            out.append(Verdict(
                quantity=item.key, channel=ALL, value=None, limit=None, rule=acceptance.rule,
                verdict="not judged", reason=f"analysis '{item.name}' is listed but does not "
                f"apply to this data; it needs {needs_text(item.cls)}"))
    return out


def limit_of(quantity: str, sheet: SensorDatasheet, acceptance: Acceptance
             ) -> tuple[float, str]:
    """The limit of a quantity and where it came from (``procedure`` or ``datasheet``)."""
    stated = getattr(acceptance.limits, quantity, None)
    source = "procedure" if stated is not None else "datasheet"
    return limits(sheet, acceptance)[quantity], source
