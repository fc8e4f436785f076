"""Preflight checks of a procedure and its plan: what would otherwise fail after the recording
(:mod:`aatest.preflight` runs them with the site's checks).

Each check returns located :class:`~aatest.engine.errors.Problem` s (empty when it passes):
an unknown plugin name at the line of the name, a report template that does not load in the
sandbox at ``report.template``, a step no listed analysis can use at the step, too little free
disk for the planned recording at the procedure's first line. Nothing here starts a plugin.
"""

from __future__ import annotations

import math
import shutil
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from aatest.engine import registry
from aatest.engine.errors import AatestError, PluginError, Problem
from aatest.engine.logs import TABLE_CHANNELS
from aatest.engine.steps import PlannedStep
from aatest.positioned_yaml import locate

#: bytes of one logged value (every channel is float64 or packed narrower; float64 bounds it)
VALUE_BYTES = 8
#: the per-step files and the merged ``recording.mcap`` coexist until the step files are pruned
COPIES = 2
#: headroom on the estimate (block headers, previews, MCAP index), a fraction
MARGIN = 0.25
#: results, report, figures and PDF of one run, bytes (a certificate with figures is ~2 MB)
REPORT_BYTES = 64 * 2**20
#: rig kinds whose plugin the procedure names (``rig:``) or a rig file sets
RIG_KINDS = ("turntable", "daq", "chamber")


def _problem(filename: str, tree: Any, path: tuple[Any, ...], message: str) -> Problem:
    line, col = locate(tree, path) if tree is not None else (1, 1)
    return Problem(filename, line, col, ".".join(map(str, path)), message)


def plugin_problems(proc: Any, rig_file: Path | None, rig_config: Any) -> list[Problem]:
    """Every plugin name that names no installed plugin: the sensor model, and the turntable,
    DAQ and chamber of the procedure's ``rig`` block (those of a rig file, ``--rig``, are
    checked, with their options, as it loads: :func:`aatest.engine.procedure.loader.load_rig`)."""
    filename = proc.source_file or f"<{proc.procedure}>"
    names = [(("sensor", "model"), "sensor", proc.sensor.model)]
    if rig_file is None:
        names += [(("rig", kind), kind, getattr(rig_config, kind).plugin) for kind in RIG_KINDS]
    problems = []
    for path, kind, name in names:
        try:
            registry.load(kind, name)
        except PluginError as exc:
            problems.append(_problem(filename, proc.source_tree, path, str(exc)))
    return problems


def template_problems(proc: Any, template_dir: Path | None = None) -> list[Problem]:
    """The report plugin exists and its template loads (parses) in the report sandbox: the
    plugin's optional ``check_template(template_dir)`` (the built-in HTML reports load their
    Jinja template in the sandbox) raises what ``render`` would."""
    filename = proc.source_file or f"<{proc.procedure}>"
    name = proc.report.template
    where = ("report", "template")
    try:
        info = registry.load("report", name)
    except PluginError as exc:
        return [_problem(filename, proc.source_tree, where, str(exc))]
    renders = getattr(info.target, "renders", "run")
    if renders != "run":  # it would be handed a run's results it cannot read
        runs = [ep.name for ep in registry.entry_points("report")
                if getattr(_loaded_or_none(ep.name), "renders", "run") == "run"]
        return [_problem(filename, proc.source_tree, where,
                         f"report {name!r} presents the document of `aatest {renders}`, not a "
                         f"run's results; choose one of: {', '.join(runs)}")]
    check = getattr(info.target, "check_template", None)
    if not callable(check):  # a vendor's reporter that states no check
        return []
    try:
        check(template_dir)
    except AatestError as exc:
        return [_problem(filename, proc.source_tree, where,
                         f"report {name!r}: its template does not load: {exc}")]
    return []


def _loaded_or_none(name: str) -> Any:
    """The report plugin ``name``'s class, or None when it does not load."""
    try:
        return registry.load("report", name).target
    except PluginError:
        return None


def _needs_table_log(proc: Any) -> list[str]:
    """The listed analyses (with what they require) that align on the table's freeze pulse."""
    from aatest.engine.analysis import passes, plugins

    names = [plugins.split_entry(e)[0] for e in proc.analysis]
    try:
        ordered = passes.order([plugins.aliases().get(n, n) for n in names])
    except PluginError:  # reported by the loader
        return []
    if not any(p.name == "sync" for p in ordered):
        return []
    return [p.name for p in ordered if p.name != "sync"]


#: the shortest full-rate table head a streamed record's clock fit accepts, s: the 100 Hz
#: freeze pulse then gives the fit ≥ 100 edges spread over a second (docs/method.md §2)
MIN_HEAD_S = 1.0


def analysable_problems(prepared: Any) -> list[Problem]:
    """A static record longer than the table's log capacity is streamed by the DAQ while the
    table logs its full-rate head (:func:`~aatest.engine.procedure.envelope.head_step`): the
    clocks are fitted on the head's freeze-pulse edges and the drift carried over the rest.
    A controller whose log holds less than :data:`MIN_HEAD_S` gives too few edges for that
    fit, so ``sync`` (and every analysis that requires it) is refused here, at the step."""
    from aatest.engine.procedure.envelope import head_step, streams_record

    proc, env = prepared.procedure, prepared.envelope
    users = _needs_table_log(proc)
    if not users or env is None:
        return []
    filename = proc.source_file or f"<{proc.procedure}>"
    sources = dict(prepared.expansion.sources)
    problems = []
    for step in prepared.plan.steps:
        if not (step.recorded and streams_record(step, env)):
            continue
        head_s = head_step(step, env).samples / step.sample_rate_hz
        if head_s >= MIN_HEAD_S:
            continue
        message = (
            f"step {step.id} records {step.samples:,} samples, more than the table's log "
            f"capacity ({env.log_capacity_samples:,} samples): the table logs only its first "
            f"{head_s:g} s, too few freeze-pulse edges for analysis 'sync'{_needed_by(users)} "
            f"to fit the clocks (needs {MIN_HEAD_S:g} s); analyse this record with 'drift' "
            "alone (it reads the DAQ stream)")
        path = tuple(sources.get(step.id, ("steps",)))
        problems.append(_problem(filename, proc.source_tree, path, message))
    return problems


def soak_problems(prepared: Any) -> list[Problem]:
    """A soak until stable needs a chamber plugin that offers ``wait_until_stable``."""
    from aatest.engine.interfaces import soaks_until_stable

    proc = prepared.procedure
    steps = [s for s in prepared.plan.steps if s.kind == "chamber" and s.soak_max_s is not None]
    name = prepared.rig_config.chamber.plugin
    if not steps or soaks_until_stable(registry.load("chamber", name).target):
        return []
    filename = proc.source_file or f"<{proc.procedure}>"
    path = (*prepared.expansion.sources.get(steps[0].id, ("steps",)), "soak")
    return [_problem(filename, proc.source_tree, path,
                     f"chamber plugin {name!r} cannot soak until stable (it has no "
                     "wait_until_stable); give a fixed soak_s instead")]


def _needed_by(users: list[str]) -> str:
    return f" (which {', '.join(users)} require{'s' * (len(users) == 1)})" if users else ""


def refuse_unrunnable(prepared: Any, out_dir: Path) -> None:
    """The plan-level preflight of a run not preflighted as a whole (a library caller of
    ``session.run``; ``run`` and the station preflight): template, analysable steps, disk."""
    from aatest.engine.errors import ProcedureError

    problems = (template_problems(prepared.procedure) + analysable_problems(prepared)
                + soak_problems(prepared) + disk_problems(prepared, out_dir)[0])
    if problems:
        raise ProcedureError(problems)


def recording_bytes(steps: Sequence[PlannedStep], envelope: Any, daq_channels: int) -> int:
    """Bytes the recording of ``steps`` may need on disk, uncompressed (noise does not compress
    much), both loggers, time stamps included, times :data:`COPIES` plus :data:`MARGIN`."""
    from aatest.engine.procedure.envelope import head_step, streams_record

    table_row = (1 + len(TABLE_CHANNELS)) * VALUE_BYTES
    daq_row = (1 + max(daq_channels, 1)) * VALUE_BYTES
    total = 0
    for step in steps:
        if not step.recorded:
            continue
        table_samples = step.samples
        if envelope is not None and streams_record(step, envelope):
            table_samples = head_step(step, envelope).samples
        total += table_samples * table_row + step.samples * daq_row
    return math.ceil(total * COPIES * (1 + MARGIN)) + REPORT_BYTES


def _existing(path: Path) -> Path:
    """The nearest existing ancestor of ``path`` (where its free space is measured)."""
    for candidate in (path, *path.absolute().parents):
        if candidate.exists():
            return candidate
    return Path.cwd()


def disk_problems(prepared: Any, out_dir: Path) -> tuple[list[Problem], str]:
    """Free space under ``out_dir`` for the planned recording (and a message either way)."""
    proc = prepared.procedure
    need = recording_bytes(prepared.plan.steps, prepared.envelope, len(prepared.daq_channels))
    where = _existing(out_dir)
    free = shutil.disk_usage(where).free
    message = (f"the recording needs up to {need / 2**20:,.0f} MiB (planned sample counts, "
               f"{COPIES} copies until merged, +{MARGIN:.0%}); {free / 2**20:,.0f} MiB free "
               f"in {where}")
    if free >= need:
        return [], message
    filename = proc.source_file or f"<{proc.procedure}>"
    return [_problem(filename, proc.source_tree, ("steps",), f"not enough disk space: {message}"
                     )], message
