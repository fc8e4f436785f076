"""The analysis pass: run the requested analysis plugins, in order, over one dataset.

Analyses read only the dataset (built from the recording or an import), so this pass can be
re-run offline at any time with ``aatest analyze``. Aliases let procedures name sub-results
(``thd``, ``snr``) that one plugin (``frf``) produces.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any

from aatest.engine import registry
from aatest.engine.dataset import Dataset
from aatest.engine.errors import AnalysisError
from aatest.engine.interfaces import AnalysisContext

log = logging.getLogger("aatest.analysis")


@dataclass
class AnalysisResults:
    values: dict[str, Any] = field(default_factory=dict)
    figures: dict[str, dict[str, str]] = field(default_factory=dict)
    errors: dict[str, str] = field(default_factory=dict)
    skipped: list[str] = field(default_factory=list)


def _aliases() -> dict[str, str]:
    try:
        from aatest.plugins.analysis import ALIASES
    except ImportError:
        return {}
    return dict(ALIASES)


def resolve_names(requested: list[str] | tuple[str, ...]) -> list[str]:
    """Plugin names in run order: aliases mapped, duplicates dropped, ``sync`` first.

    With no request, every installed analysis runs (each decides whether it applies).
    """
    aliases = _aliases()
    names = list(requested) or [ep.name for ep in registry.entry_points("analysis")]
    ordered: list[str] = []
    for name in names:
        plugin = aliases.get(name, name)
        if plugin not in ordered:
            ordered.append(plugin)
    if "sync" in ordered:
        ordered.remove("sync")
        ordered.insert(0, "sync")
    return ordered


def run_analyses(data: Dataset, requested: list[str] | tuple[str, ...]) -> AnalysisResults:
    """Run each analysis; a data problem in one is recorded and the others still run."""
    out = AnalysisResults()
    context = AnalysisContext(results=out.values)
    explicit = bool(requested)
    for name in resolve_names(requested):
        info = registry.load("analysis", name)
        plugin = info.target()
        key = getattr(plugin, "key", name)
        if not plugin.applies_to(data):
            out.skipped.append(name)
            if explicit:
                log.warning("analysis %r does not apply to this data; skipped", name)
            continue
        try:
            result = plugin.run(data, context)
        except AnalysisError as exc:
            out.errors[name] = str(exc)
            log.error("analysis %r: %s", name, exc)
            continue
        out.values[key] = result.values
        if result.figures:
            out.figures[key] = dict(result.figures)
    return out
