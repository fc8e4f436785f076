"""Plugin discovery through installed entry points only (never from paths or strings in YAML).

Each plugin is validated when it is loaded: it must provide the methods of its kind's
``Protocol`` and a pydantic ``Config`` model; errors name the plugin and the distribution that
installed it, so a user knows which package is at fault.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ValidationError

from aatest.engine.errors import PluginError
from aatest.engine.interfaces import GROUPS
from aatest.plugin_options import RIG_DIR

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
#: kinds whose options are not a ``Config`` model (an effect has typed ``parameters`` instead;
#: its declaration is checked by :mod:`aatest.effects`)
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


#: entry points by kind, with the installation signature they were read under
_SCANNED: dict[str, tuple[tuple[Any, ...], list[metadata.EntryPoint]]] = {}


def _installed_signature() -> tuple[Any, ...]:
    """What the installed entry points depend on, cheaply: the metadata API in use, the import
    path with each directory's modification time, and every distribution's ``entry_points.txt``
    modification time and size (ns, bytes).

    Why: reading every distribution's entry points takes ≈3.6 ms and a run asks ≈270 times
    (≈1 s); stat calls take ≈0.6 ms. A distribution installed, removed or edited since (a test
    writing a ``.dist-info`` on ``sys.path``, or monkeypatching ``importlib.metadata``) changes
    the signature, so plugins still come only from what is installed now.
    """
    stamps: list[Any] = [metadata.entry_points, tuple(sys.path)]
    for entry in sys.path:
        try:
            stamps.append(os.stat(entry or ".").st_mtime_ns)
        except OSError:
            stamps.append(None)
    for dist in metadata.distributions():
        where = getattr(dist, "_path", None)  # a PathDistribution's .dist-info directory
        if where is None:
            stamps.append(id(dist))  # unknown kind of distribution: never reuse the scan
            continue
        try:
            found = os.stat(os.path.join(where, "entry_points.txt"))
        except OSError:
            stamps.append(str(where))
            continue
        stamps.append((str(where), found.st_mtime_ns, found.st_size))
    return tuple(stamps)


#: the installation signature pinned by :func:`pinned` (per thread: a context variable)
_PINNED: ContextVar[tuple[Any, ...] | None] = ContextVar("aatest_registry_pinned", default=None)
#: plugins loaded and validated while pinned, by (kind, name), with the pinned signature object
#: they were loaded under (reused only inside that same block: each run loads afresh)
_LOADED: dict[tuple[str, str], tuple[tuple[Any, ...], PluginInfo]] = {}


@contextmanager
def pinned() -> Iterator[None]:
    """Read the installed entry points once for the block (a run, an analysis, a diagnosis).

    Why: a run asks for plugins hundreds of times (every analysis looks up the aliases of all
    installed analyses); even the cheap :func:`_installed_signature` (≈2 ms) and reading a
    distribution's name and version (≈2 ms) then add up to a second of an ``aatest run``.
    Inside the block the installation is taken as it was on entry, and each plugin is loaded
    and validated once. Nested blocks share the outer one's reading; other threads (the
    station's) are not affected.
    """
    if _PINNED.get() is not None:
        yield
        return
    token = _PINNED.set(_installed_signature())
    try:
        yield
    finally:
        _PINNED.reset(token)


def _signature() -> tuple[Any, ...]:
    """The pinned installation signature, else the installation's as it is now."""
    return _PINNED.get() or _installed_signature()


def entry_points(kind: str) -> list[metadata.EntryPoint]:
    """Return the installed entry points of one plugin kind, sorted by name.

    Read once per process and re-read whenever the installation changes
    (:func:`_installed_signature`); the list returned is the caller's own.
    """
    if kind not in GROUPS:
        raise PluginError(f"unknown plugin kind {kind!r}; kinds: {', '.join(GROUPS)}")
    signature = _signature()
    cached = _SCANNED.get(kind)
    if cached is None or cached[0] != signature:
        found = sorted(metadata.entry_points(group=GROUPS[kind]), key=lambda ep: ep.name)
        _SCANNED[kind] = cached = (signature, found)
    return list(cached[1])


def load(kind: str, name: str) -> PluginInfo:
    """Load and validate the ``kind`` plugin called ``name`` (once per :func:`pinned` block)."""
    pin = _PINNED.get()
    if pin is not None:
        known = _LOADED.get((kind, name))
        if known is not None and known[0] is pin:  # loaded in this very block
            return known[1]
    info = _load(kind, name)
    if pin is not None:
        _LOADED[(kind, name)] = (pin, info)
    return info


def _load(kind: str, name: str) -> PluginInfo:
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


def configure(info: PluginInfo, options: dict[str, Any], rig_dir: Path | None = None
              ) -> BaseModel | None:
    """Validate a plugin's options against its own ``Config`` model; ``rig_dir``, the rig
    file's directory, is where a relative :data:`aatest.plugin_options.RigFilePath` lies."""
    model = info.config_model
    if model is None:
        if options:
            raise PluginError(f"{info.kind} plugin {info.name!r} takes no options")
        return None
    try:
        return model.model_validate(options, context={RIG_DIR: rig_dir})
    except ValidationError as exc:
        detail = "; ".join(
            f"{'.'.join(str(p) for p in e['loc'])}: {e['msg']}"
            for e in exc.errors(include_url=False)
        )
        raise PluginError(
            f"{info.kind} plugin {info.name!r} ({info.distribution}): bad options: {detail}"
        ) from exc
