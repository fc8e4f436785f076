"""The analysis pass: run the requested analysis plugins over one dataset, in dependency order.

Analyses read only the dataset (built from the recording or an import), so this pass can be
re-run offline at any time with ``aatest analyze``. Each plugin declares what it ``requires``;
a requested analysis pulls those in, and the pass runs them first (a topological order, ties
broken by name), handing each plugin only the outputs of its own requirements. So the results
never depend on the order names are listed in. Aliases let procedures name sub-results
(``thd``, ``snr``) that one plugin (``frf``) produces.

Decoding a recorded step costs more than most analyses of it, so before any plugin runs each
may register small per-step reductions (its optional ``watch_steps``; the uncertainty
evidence too): the sync pass, which decodes every step first, then decodes the union of the
channels once and feeds them all (:mod:`aatest.plugins.analysis.sync`). Results are the same
as when each analysis reads the steps itself.
"""

from __future__ import annotations

import gc
import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from graphlib import CycleError, TopologicalSorter
from types import MappingProxyType
from typing import Any

from pydantic import BaseModel
from threadpoolctl import threadpool_limits

from aatest.engine.analysis import plugins as _plugins
from aatest.engine.analysis.plugins import AnalysisEntry, AnalysisPlugin
from aatest.engine.errors import AnalysisError, PluginError
from aatest.engine.interfaces import AnalysisContext, AnalysisOutput
from aatest.parallel.gc_freeze import older_objects_frozen
from aatest.recording import temperatures
from aatest.recording.dataset import Dataset

log = logging.getLogger("aatest.analysis")


@dataclass
class AnalysisResults:
    """Typed outputs by analysis key, and what failed or did not apply (by plugin name)."""

    outputs: dict[str, AnalysisOutput[Any]] = field(default_factory=dict)
    errors: dict[str, str] = field(default_factory=dict)
    skipped: list[str] = field(default_factory=list)

    @property
    def values(self) -> dict[str, Any]:
        """Key → typed result."""
        return {key: out.result for key, out in self.outputs.items()}

    @property
    def figures(self) -> dict[str, dict[str, str]]:
        """Key → figure name → SVG, for the analyses that drew any."""
        return {key: dict(out.figures) for key, out in self.outputs.items() if out.figures}


def _with_requirements(names: Sequence[str]) -> dict[str, AnalysisPlugin]:
    """The named plugins and, transitively, every plugin they require."""
    found: dict[str, AnalysisPlugin] = {}
    todo: list[tuple[str, AnalysisPlugin | None]] = [(n, None) for n in reversed(names)]
    while todo:
        name, requirer = todo.pop()
        if name in found:
            continue
        try:
            found[name] = _plugins.load(name)
        except PluginError as exc:
            if requirer is None:
                raise
            raise PluginError(f"{requirer.describe()} requires {name!r}: {exc}") from exc
        todo.extend((r, found[name]) for r in found[name].requires)
    return found


def order(names: Sequence[str]) -> list[AnalysisPlugin]:
    """Plugins in run order: requirements first, otherwise by name.

    Raises
    ------
    PluginError
        When a plugin requires an analysis that is not installed, or requirements form a cycle
        (the error names the plugins and their distributions).
    """
    by_name = _with_requirements(names)
    graph = TopologicalSorter({n: sorted(by_name[n].requires) for n in sorted(by_name)})
    try:
        return [by_name[n] for n in graph.static_order()]
    except CycleError as exc:
        cycle = [by_name[n].describe() for n in dict.fromkeys(exc.args[1])]
        raise PluginError("analysis requirements form a cycle: " + " → ".join(cycle)) from exc


def requested_names(entries: Sequence[AnalysisEntry]) -> list[str]:
    """The plugin names procedure ``analysis:`` entries ask for (aliases resolved), once each;
    every installed analysis when there are none (each then decides whether it applies)."""
    if not entries:
        return _plugins.installed_names()
    aliases = _plugins.aliases()
    names = [aliases.get(n, n) for n in (_plugins.split_entry(e)[0] for e in entries)]
    return list(dict.fromkeys(names))


def _run_one(plugin: AnalysisPlugin, data: Dataset, options: BaseModel,
             done: Mapping[str, AnalysisOutput[Any]]) -> AnalysisOutput[Any]:
    """Run one plugin with the outputs of its requirements (those that produced one)."""
    upstream = MappingProxyType({r: done[r] for r in plugin.requires if r in done})
    out = plugin.cls().run(data, AnalysisContext(options=options, upstream=upstream))
    if not isinstance(out, AnalysisOutput) or not isinstance(out.result, plugin.cls.Result):
        raise PluginError(f"{plugin.describe()} returned {type(out).__name__}, not an "
                          f"AnalysisOutput holding its {plugin.cls.Result.__name__}")
    return out


def _watch_steps(plugins: Sequence[AnalysisPlugin], data: Dataset,
                 chosen: Mapping[str, BaseModel]) -> None:
    """Let every plugin that applies register its per-step reductions before any plugin runs.

    An analysis plugin may define ``watch_steps(data, options)`` (optional; ``options`` as its
    ``run`` gets them): it registers reductions the first pass over the recording makes while
    it decodes each step (:func:`aatest.plugins.analysis.sync.watch_synced`), so each step is
    decoded once for all analyses instead of once per analysis. Results are the same either
    way: a plugin without it, or run alone, reads the steps itself.
    """
    for plugin in plugins:
        if callable(getattr(plugin.cls, "watch_steps", None)) and plugin.cls().applies_to(data):
            plugin.cls().watch_steps(data, chosen.get(plugin.name) or plugin.options())


def run_analyses(data: Dataset, requested: Sequence[AnalysisEntry],
                 options: Mapping[str, BaseModel] | None = None) -> AnalysisResults:
    """Run each analysis; a data problem in one is recorded and the others still run.

    Parameters
    ----------
    data
        The dataset to analyse.
    requested
        Procedure ``analysis:`` entries (names or ``{name: {options}}``); empty: every
        installed analysis (each decides whether it applies).
    options
        Already validated options by plugin name, overriding those in ``requested``.

    BLAS runs on one thread here: the analyses' matrices are small (least-squares designs of a
    few columns), where OpenBLAS's worker threads only spin — measured on the stepped sine,
    ≈ 9 s of CPU time on the second core for no gain in wall time, CPU the pass's forked
    workers (:func:`aatest.plugins.analysis.sync.relations`) use instead.
    """
    with threadpool_limits(limits=1, user_api="blas"), older_objects_frozen():
        return _run_analyses(data, requested, options)


@dataclass(frozen=True)
class Watched:
    """The analyses a pass runs, resolved, once their per-step reductions are registered."""

    #: the plugins in run order (requirements first)
    plugins: list[AnalysisPlugin]
    #: the names asked for (after aliases), or every installed analysis
    names: list[str]
    #: validated options by plugin name (those given; the others use their defaults)
    chosen: dict[str, BaseModel]
    #: whether the analyses were named (else every installed one, each deciding if it applies)
    explicit: bool


def register_watches(data: Dataset, requested: Sequence[AnalysisEntry],
                     options: Mapping[str, BaseModel] | None = None) -> Watched:
    """Resolve the requested analyses and register every per-step reduction the pass makes
    while it decodes each step: the uncertainty evidence, the logged temperatures and each
    applicable plugin's ``watch_steps``.

    One function for the analysis pass and for the analysis a run makes of each step while it
    still records (:mod:`aatest.early.analysis`): both then reduce a step the
    same way.
    """
    from aatest.metrology.uncertainty.evidence import watch

    # the uncertainty stage and the results' logged-temperature summary read every step after
    # this pass: measured while the pass decodes them, they need not decode them again
    watch(data)
    temperatures.watch(data)
    explicit = bool(requested)
    names = requested_names(requested)
    chosen = dict(_plugins.requested_options(requested)) | dict(options or {})
    plugins = order(names)
    _watch_steps(plugins, data, chosen)
    return Watched(plugins, names, chosen, explicit)


def _run_analyses(data: Dataset, requested: Sequence[AnalysisEntry],
                  options: Mapping[str, BaseModel] | None) -> AnalysisResults:
    watched = register_watches(data, requested, options)
    plugins, names, chosen, explicit = (watched.plugins, watched.names, watched.chosen,
                                        watched.explicit)
    out = AnalysisResults()
    by_name: dict[str, AnalysisOutput[Any]] = {}
    for plugin in plugins:
        if not plugin.cls().applies_to(data):
            out.skipped.append(plugin.name)
            if explicit and plugin.name in names:
                log.warning("analysis %r does not apply to this data; skipped", plugin.name)
            continue
        try:
            result = _run_one(plugin, data, chosen.get(plugin.name) or plugin.options(), by_name)
        except AnalysisError as exc:
            out.errors[plugin.name] = str(exc)
            log.error("analysis %r: %s", plugin.name, exc)
            continue
        out.outputs[plugin.key] = by_name[plugin.name] = result
        # A plugin's decoded records can stay alive in reference cycles after it returns
        # (matplotlib's text parser keeps exceptions whose tracebacks hold the caller's frames,
        # measured: ≈440 MB of a 2 h record until the next automatic collection); collecting
        # here keeps the pass at one plugin's working set.
        gc.collect()
    return out


def run_analysis(name: str, data: Dataset, options: Mapping[str, Any] | None = None
                 ) -> AnalysisOutput[Any]:
    """Run one analysis (and what it requires, with default options) and return its output.

    Raises
    ------
    AnalysisError
        When it, or an analysis it requires, fails, or when it does not apply to ``data``.
    """
    plugin = _plugins.load(name)
    done = run_analyses(data, [name], {plugin.name: plugin.options(options)})
    if plugin.key not in done.outputs:
        reason = done.errors.get(plugin.name) or "; ".join(done.errors.values()) \
            or "it does not apply to this data"
        raise AnalysisError(f"analysis {name!r} produced no result: {reason}")
    return done.outputs[plugin.key]
