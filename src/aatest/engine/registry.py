"""Plugin discovery through installed entry points only (never from paths or strings in YAML).

Each plugin is validated when it is loaded: it must provide the methods of its kind's
``Protocol`` and a pydantic ``Config`` model; errors name the plugin and the distribution that
installed it, so a user knows which package is at fault.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import metadata
from typing import Any

from pydantic import BaseModel, ValidationError

from aatest.engine.errors import PluginError
from aatest.engine.interfaces import GROUPS

#: methods each kind must implement (checked on the class, before anything is constructed)
REQUIRED_METHODS: dict[str, tuple[str, ...]] = {
    "turntable": ("envelope", "start", "move_to", "begin_motion", "record", "end_motion",
                  "safe_stop", "close"),
    "daq": ("channels", "start", "start_logging", "stop_logging", "close"),
    "chamber": ("set_temperature", "wait_stable", "off", "close"),
    "sensor": ("datasheet",),
    "analysis": ("applies_to", "run"),
    "report": ("render",),
    "effect": ("columns", "forward", "testable", "signature"),
}
#: kinds whose options are not a ``Config`` model (an effect has typed ``parameters`` instead,
#: checked by :mod:`aatest.effects` when it is loaded)
_NO_CONFIG = frozenset({"analysis", "effect"})


@dataclass(frozen=True)
class PluginInfo:
    """A discovered plugin: its kind, name, implementing object and distribution."""

    kind: str
    name: str
    target: Any
    distribution: str
    version: str

    @property
    def config_model(self) -> type[BaseModel] | None:
        """Return the plugin's options model (its ``Config`` attribute), if it has one."""
        return getattr(self.target, "Config", None)


def _distribution(ep: metadata.EntryPoint) -> tuple[str, str]:
    dist = getattr(ep, "dist", None)
    if dist is None:
        return "unknown", "unknown"
    return dist.metadata["Name"], dist.version


def _validate(kind: str, name: str, target: Any, dist: str) -> None:
    missing = [m for m in REQUIRED_METHODS[kind] if not callable(getattr(target, m, None))]
    if missing:
        raise PluginError(
            f"{kind} plugin {name!r} from distribution {dist!r} lacks required method(s) "
            f"{', '.join(missing)}"
        )
    config = getattr(target, "Config", None)
    if kind not in _NO_CONFIG and not (isinstance(config, type) and issubclass(config, BaseModel)):
        raise PluginError(
            f"{kind} plugin {name!r} from distribution {dist!r} must define a pydantic "
            f"'Config' model for its options"
        )


def entry_points(kind: str) -> list[metadata.EntryPoint]:
    """Return the installed entry points of one plugin kind, sorted by name."""
    if kind not in GROUPS:
        raise PluginError(f"unknown plugin kind {kind!r}; kinds: {', '.join(GROUPS)}")
    return sorted(metadata.entry_points(group=GROUPS[kind]), key=lambda ep: ep.name)


def load(kind: str, name: str) -> PluginInfo:
    """Load and validate the ``kind`` plugin called ``name``."""
    matches = [ep for ep in entry_points(kind) if ep.name == name]
    if not matches:
        known = ", ".join(ep.name for ep in entry_points(kind)) or "none installed"
        raise PluginError(f"no {kind} plugin named {name!r} (installed: {known})")
    ep = matches[0]
    dist, version = _distribution(ep)
    try:
        target = ep.load()
    except Exception as exc:  # any import failure is the plugin's fault
        raise PluginError(
            f"{kind} plugin {name!r} from distribution {dist!r} failed to import: {exc}"
        ) from exc
    _validate(kind, name, target, dist)
    return PluginInfo(kind, name, target, dist, version)


def discover(kind: str) -> list[PluginInfo]:
    """Every installed plugin of a kind, each validated (a broken one raises)."""
    return [load(kind, ep.name) for ep in entry_points(kind)]


def configure(info: PluginInfo, options: dict[str, Any]) -> BaseModel | None:
    """Validate a plugin's options against its own ``Config`` model."""
    model = info.config_model
    if model is None:
        if options:
            raise PluginError(f"{info.kind} plugin {info.name!r} takes no options")
        return None
    try:
        return model.model_validate(options)
    except ValidationError as exc:
        detail = "; ".join(
            f"{'.'.join(str(p) for p in e['loc'])}: {e['msg']}"
            for e in exc.errors(include_url=False)
        )
        raise PluginError(
            f"{info.kind} plugin {info.name!r} ({info.distribution}): bad options: {detail}"
        ) from exc
