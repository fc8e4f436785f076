"""Analysis plugins as the engine sees them: loaded, validated, their options parsed.

A procedure's ``analysis:`` entry is a plugin name (or an alias such as ``thd``) or a one-key
mapping ``{name: {options}}``; the options are validated by the plugin's own ``Options`` model,
both when the procedure is loaded (located errors, exit 2) and again when the analyses run
(the options travel with the recording, so ``aatest analyze`` re-runs exactly what was asked).
"""

from __future__ import annotations

import json
import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from pydantic import BaseModel, ValidationError

from aatest.engine import registry
from aatest.engine.errors import InputError, PluginError
from aatest.metrology.verdicts_missing import Listed

#: a procedure ``analysis:`` entry as written: ``name`` or ``{name: {options}}``
AnalysisEntry = str | Mapping[str, Mapping[str, Any] | None]


log = logging.getLogger("aatest.analysis")


@dataclass(frozen=True)
class AnalysisPlugin:
    """One installed analysis: its entry-point name, class and distribution."""

    name: str
    cls: Any
    distribution: str

    @property
    def key(self) -> str:
        """The plugin's key in ``results.json`` → ``analysis``."""
        return str(self.cls.key)

    @property
    def requires(self) -> tuple[str, ...]:
        """Names of the analyses whose outputs this one reads (run before it)."""
        return tuple(self.cls.requires)

    def options(self, raw: Mapping[str, Any] | None = None) -> BaseModel:
        """The validated options (pydantic ``ValidationError`` on a bad one).

        Validated strictly as the JSON values they are (in YAML, in the recording), like
        every procedure field: ``"5"`` is not a number, ``true`` not 1.
        """
        model: type[BaseModel] = self.cls.Options
        return model.model_validate_json(json.dumps(dict(raw or {}), default=str), strict=True)

    def describe(self) -> str:
        """How errors name the plugin: its entry-point name and distribution."""
        return f"analysis plugin {self.name!r} from distribution {self.distribution!r}"


def aliases() -> dict[str, str]:
    """Procedure names computed inside another plugin (``thd``/``snr`` → ``frf``).

    A plugin declares them as ``aliases: ClassVar[tuple[str, ...]]``; the engine learns them
    by loading every installed analysis entry point (plugins come only from entry points), once
    per :func:`aatest.engine.registry.pinned` block (a run reads them once). Loading the
    analyses a procedure does not use costs little: measured, 34 ms of CPU for the eight the
    stepped sine does not list, whose heavy imports (NumPy, SciPy) the others share.
    """
    found: dict[str, str] = {}
    for entry in registry.entry_points("analysis"):
        try:
            info = registry.load("analysis", entry.name)
        except PluginError as exc:  # named when used; a broken plugin has no aliases to offer
            log.warning("%s", exc)
            continue
        for alias in getattr(info.target, "aliases", ()):
            found.setdefault(str(alias), info.name)
    return found


def _check_options_model(plugin: AnalysisPlugin) -> None:
    options = getattr(plugin.cls, "Options", None)
    if not (isinstance(options, type) and issubclass(options, BaseModel)):
        raise PluginError(f"{plugin.describe()} must define a pydantic 'Options' model")
    config = options.model_config
    if config.get("extra") != "forbid" or not config.get("frozen"):
        raise PluginError(f"{plugin.describe()}: 'Options' must be frozen with extra='forbid'")
    try:
        options()
    except ValidationError as exc:
        raise PluginError(f"{plugin.describe()}: every option needs a default ({exc.error_count()}"
                          " without one)") from exc


def validate_plugin(plugin: AnalysisPlugin) -> None:
    """Check the class attributes the engine relies on; the error names the distribution."""
    cls = plugin.cls
    key, requires = getattr(cls, "key", None), getattr(cls, "requires", None)
    if not isinstance(key, str) or not key:
        raise PluginError(f"{plugin.describe()} must define a non-empty string 'key'")
    if not isinstance(requires, tuple) or not all(isinstance(r, str) for r in requires):
        raise PluginError(f"{plugin.describe()}: 'requires' must be a tuple of analysis names")
    if not isinstance(getattr(cls, "Result", None), type):
        raise PluginError(f"{plugin.describe()} must define its 'Result' type")
    _check_options_model(plugin)


def load(name: str) -> AnalysisPlugin:
    """Load and validate the analysis plugin installed as ``name`` (aliases resolved)."""
    info = registry.load("analysis", aliases().get(name, name))
    plugin = AnalysisPlugin(info.name, info.target, info.distribution)
    validate_plugin(plugin)
    return plugin


def installed_names() -> list[str]:
    """Entry-point names of every installed analysis."""
    return [ep.name for ep in registry.entry_points("analysis")]


def split_entry(entry: AnalysisEntry) -> tuple[str, dict[str, Any]]:
    """``name`` or ``{name: {options}}`` → (name, options)."""
    if isinstance(entry, str):
        return entry, {}
    if isinstance(entry, Mapping) and len(entry) == 1:
        (name, options), = entry.items()
        if options is None or isinstance(options, Mapping):
            return str(name), dict(options or {})
    raise InputError(f"analysis entry {entry!r}: expected a name or {{name: {{options}}}}")


@dataclass(frozen=True)
class OptionClash:
    """Entry ``index`` gives analysis ``plugin`` options other than entry ``first``'s."""

    index: int
    plugin: str
    first: int


def option_clashes(entries: Sequence[AnalysisEntry]) -> list[OptionClash]:
    """Every entry that gives an analysis (aliases resolved) options other than those an
    earlier entry gave it: the run could not tell which to use. An entry without options
    beside one with them is no clash (the options apply), nor are equal options twice."""
    given: dict[str, tuple[int, dict[str, Any]]] = {}
    clashes = []
    for index, entry in enumerate(entries):
        name, options = split_entry(entry)
        plugin_name = aliases().get(name, name)
        if not options:
            continue
        first = given.setdefault(plugin_name, (index, options))
        if first[1] != options:
            clashes.append(OptionClash(index, plugin_name, first[0]))
    return clashes


def requested_options(entries: Sequence[AnalysisEntry]) -> dict[str, BaseModel]:
    """Plugin name → validated options for every requested analysis (aliases merged).

    Raises
    ------
    InputError
        When options are invalid or one analysis is given two different sets of options.
    """
    clashes = option_clashes(entries)
    if clashes:
        raise InputError(f"analysis {clashes[0].plugin!r} is given two different sets of "
                         "options")
    raw: dict[str, dict[str, Any]] = {}
    for entry in entries:
        name, options = split_entry(entry)
        plugin_name = aliases().get(name, name)
        if options or plugin_name not in raw:
            raw[plugin_name] = options
    out: dict[str, BaseModel] = {}
    for name, options in raw.items():
        plugin = load(name)
        try:
            out[name] = plugin.options(options)
        except ValidationError as exc:
            raise InputError(f"{plugin.describe()}: bad options: {exc}") from exc
    return out


def listed_analyses(entries: Sequence[Any]) -> list[Listed]:
    """The analyses a recording's procedure listed (aliases resolved, each once), for the
    verdict stage."""
    out: dict[str, Listed] = {}
    for entry in entries:
        try:
            name, _options = split_entry(entry)
            plugin = load(name)
        except (InputError, PluginError) as exc:  # named by the analysis pass already
            log.debug("%s", exc)
            continue
        out.setdefault(plugin.name, Listed(plugin.name, plugin.key, plugin.cls))
    return list(out.values())


def installed_analyses() -> list[Listed]:
    """Every installed analysis that loads, for the verdict stage's reasons."""
    out = []
    for name in installed_names():
        try:
            plugin = load(name)
        except PluginError:
            continue
        out.append(Listed(plugin.name, plugin.key, plugin.cls))
    return out
