"""Before anything moves: does the plan hold what each listed analysis needs, and does some
listed analysis produce each quantity the acceptance asks to judge?

Every analysis the procedure lists is checked against its declared requirements
(:mod:`aatest.engine.requirements`); an unmet one is a located problem at the analysis entry
(or the step it names). A quantity the acceptance asks for (``acceptance.judge``, or a limit
set without it) that no listed analysis can produce is a problem at that entry: the run could
only end ``incomplete``, so it is refused before it starts. All are reported at once through
one ``ProcedureError`` (exit 2).
``aatest validate`` prints which steps each analysis will use (:func:`usage_lines`).
"""

from __future__ import annotations

from typing import Any

from aatest.engine.analysis import plugins
from aatest.engine.errors import PluginError, Problem, ProcedureError
from aatest.engine.interfaces import SensorDatasheet
from aatest.engine.procedure.models import Procedure
from aatest.engine.requirements import Coverage, PlanView, check_plan
from aatest.engine.steps import Plan
from aatest.metrology.verdicts_missing import acceptance_problems
from aatest.positioned_yaml import locate

#: step ids ``validate`` shows per analysis before it gives the count
SHOWN = 3


def _listed(proc: Procedure) -> dict[str, tuple[int, Any]]:
    """Plugin name → (index of its analysis entry, plugin class), aliases resolved."""
    out: dict[str, tuple[int, Any]] = {}
    for index, entry in enumerate(proc.analysis):
        name, _options = plugins.split_entry(entry)
        try:
            plugin = plugins.load(name)
        except PluginError:  # reported by the loader already
            continue
        out.setdefault(plugin.name, (index, plugin.cls))
    return out


def _pulled_in(listed: dict[str, tuple[int, Any]]) -> dict[str, tuple[int, Any]]:
    """``sync`` when a listed analysis requires it and the procedure does not list it: the
    pass runs it, and the requirer reads the steps it synchronises, so its requirements
    hold as well (name → (index of the first entry that requires it, plugin class)). Other
    requirements are used where they apply (``noise`` takes ``scale_factor``'s output on a
    plan with sine steps and works without it), so their needs are not the requirer's."""
    from aatest.engine.analysis import passes

    if "sync" in listed:
        return {}
    for name, (index, _cls) in listed.items():
        try:
            ordered = passes.order([name])
        except PluginError:  # named by the loader
            continue
        found = next((p for p in ordered if p.name == "sync"), None)
        if found is not None:
            return {"sync": (index, found.cls)}
    return {}


def check_coverage(proc: Procedure, plan: Plan, sources: dict[str, Any], chamber: str,
                   datasheet: SensorDatasheet) -> Coverage:
    """Check the listed analyses' requirements; raise the unmet ones, located.

    Raises
    ------
    ProcedureError
        One problem per unmet requirement, at the step it names or the analysis entry.
    """
    listed = _listed(proc)
    pulled = _pulled_in(listed)
    checked = listed | pulled
    view = PlanView(plan.steps, chamber, dict(datasheet.channels))
    coverage = check_plan({name: cls for name, (_i, cls) in checked.items()}, view)
    for name in pulled:  # validate shows the steps of the analyses the procedure lists
        coverage.uses.pop(name, None)
    filename = proc.source_file or f"<{proc.procedure}>"
    problems = []
    for unmet in coverage.unmet:
        index = checked[unmet.analysis][0]
        entry = proc.analysis[index]
        named = plugins.split_entry(entry)[0]
        path: tuple[Any, ...] = ("analysis", index) + (
            () if isinstance(entry, str) else (named,))
        if unmet.step_id is not None and unmet.step_id in sources:
            path = tuple(sources[unmet.step_id])
        line, col = locate(proc.source_tree, path) if proc.source_tree else (1, 1)
        by = f" (which '{named}' requires)" if unmet.analysis in pulled else ""
        problems.append(Problem(filename, line, col, ".".join(map(str, path)),
                                f"analysis '{unmet.analysis}'{by} {unmet.message}"))
    problems += acceptance_problems(proc, plugins.listed_analyses(proc.analysis),
                                    plugins.installed_analyses, filename, view,
                                    {name: index for name, (index, _cls) in listed.items()})
    if problems:
        raise ProcedureError(problems)
    return coverage


def usage_lines(coverage: Coverage) -> list[str]:
    """What ``validate`` prints: per analysis, the steps it will use."""
    lines = []
    for name, used in coverage.uses.items():
        shown = ", ".join(used[:SHOWN]) + (f", … ({len(used)} steps)" if len(used) > SHOWN
                                           else "")
        lines.append(f"  {name}: {shown or 'no recorded step'}")
    return (["analyses and the steps each will use:", *lines]) if lines else []


def requirements_markdown() -> str:
    """The requirements table of docs/interfaces.md, from the built-in analyses' declarations
    (a test checks the document holds exactly this)."""
    from aatest.engine.requirements import judges_of, measures_of, produces_of, requirements_of

    rows = ["| analysis | needs (checked by `validate`) | judges |", "|---|---|---|"]
    for name in sorted(plugins.installed_names()):
        try:
            plugin = plugins.load(name)
        except PluginError:
            continue
        if plugin.distribution != "aatest":
            continue
        declared = requirements_of(plugin.cls)
        needs = "; ".join(r.need for r in declared) if declared is not None else "not declared"
        produces = produces_of(plugin.cls)
        judged = ", ".join(f"`{q}`" + (f" (from {produces[q].need})" if q in produces else "")
                           for q in judges_of(plugin.cls)) or "—"
        extra = [q for q in measures_of(plugin.cls) if q not in judges_of(plugin.cls)]
        judged += "".join(f"; `{q}` where measured" for q in extra)
        rows.append(f"| `{name}` | {needs} | {judged} |")
    return "\n".join(rows) + "\n"
