"""Before anything moves: does the plan hold what each listed analysis needs?

Every analysis the procedure lists is checked against its declared requirements
(:mod:`aatest.engine.requirements`); an unmet one is a located problem at the analysis entry
(or the step it names), all reported at once through one ``ProcedureError`` (exit 2).
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


def check_coverage(proc: Procedure, plan: Plan, sources: dict[str, Any], chamber: str,
                   datasheet: SensorDatasheet) -> Coverage:
    """Check the listed analyses' requirements; raise the unmet ones, located.

    Raises
    ------
    ProcedureError
        One problem per unmet requirement, at the step it names or the analysis entry.
    """
    listed = _listed(proc)
    view = PlanView(plan.steps, chamber, dict(datasheet.channels))
    coverage = check_plan({name: cls for name, (_i, cls) in listed.items()}, view)
    filename = proc.source_file or f"<{proc.procedure}>"
    problems = []
    for unmet in coverage.unmet:
        index = listed[unmet.analysis][0]
        entry = proc.analysis[index]
        path: tuple[Any, ...] = ("analysis", index) + (
            () if isinstance(entry, str) else (unmet.analysis,))
        if unmet.step_id is not None and unmet.step_id in sources:
            path = tuple(sources[unmet.step_id])
        line, col = locate(proc.source_tree, path) if proc.source_tree else (1, 1)
        problems.append(Problem(filename, line, col, ".".join(map(str, path)),
                                f"analysis '{unmet.analysis}' {unmet.message}"))
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
    from aatest.engine.requirements import judges_of, measures_of, requirements_of

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
        judged = ", ".join(f"`{q}`" for q in judges_of(plugin.cls)) or "—"
        extra = [q for q in measures_of(plugin.cls) if q not in judges_of(plugin.cls)]
        judged += "".join(f"; `{q}` where measured" for q in extra)
        rows.append(f"| `{name}` | {needs} | {judged} |")
    return "\n".join(rows) + "\n"
