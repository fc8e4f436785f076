"""Building the rig from plugin names and owning its life cycle.

The engine, not the plugins, decides when a rig starts and stops: if one plugin fails to start,
the ones already started are brought to a safe state and closed, and the error names the
plugin that failed. Any fault while running ends in ``safe_stop`` (table stopped, motor off).
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

from aatest.engine import registry
from aatest.engine.dataset import SensorInfo
from aatest.engine.errors import AatestError, PluginError, RigFault
from aatest.engine.interfaces import Chamber, Daq, RigContext, SensorDatasheet, Turntable
from aatest.engine.steps import SensorRef

log = logging.getLogger("aatest.rig")


@dataclass
class Rig:
    """The constructed (not yet started) plugins of one rig."""

    turntable: Turntable
    daq: Daq
    chamber: Chamber
    datasheet: SensorDatasheet
    context: RigContext
    versions: dict[str, str] = field(default_factory=dict)
    config: dict[str, Any] = field(default_factory=dict)

    def sensor_infos(self) -> tuple[SensorInfo, ...]:
        """The sensors under test on this rig, one record per sensing axis, with their serials.

        Derived from the one datasheet and the procedure's serial (not copied field by field),
        so the recording's metadata and the verdicts' limits name the same sensors.
        """
        return self.datasheet.sensor_infos(self.context.sensor.serial)


def sensor_datasheet(sensor: SensorRef) -> tuple[SensorDatasheet, str]:
    """Resolve a procedure's sensor model through the ``aatest.sensors`` plugins."""
    info = registry.load("sensor", sensor.model)
    plugin = info.target(registry.configure(info, {}), None)
    sheet = plugin.datasheet()
    if not isinstance(sheet, SensorDatasheet):
        raise PluginError(
            f"sensor plugin {sensor.model!r} ({info.distribution}) returned "
            f"{type(sheet).__name__}, expected SensorDatasheet"
        )
    return sheet, f"{info.distribution} {info.version}"


def _construct(
    kind: str, name: str, options: dict[str, Any], context: RigContext
) -> tuple[Any, str]:
    info = registry.load(kind, name)
    config = registry.configure(info, options)
    try:
        plugin = info.target(config, context)
    except AatestError:
        raise
    except Exception as exc:
        raise PluginError(f"{kind} plugin {name!r} ({info.distribution}) failed: {exc}") from exc
    return plugin, f"{info.distribution} {info.version}"


def build_rig(rig_config: Any, sensor: SensorRef, seed: int) -> Rig:
    """Construct turntable, DAQ and chamber plugins; nothing is connected or moved yet."""
    datasheet, sensor_version = sensor_datasheet(sensor)
    context = RigContext(sensor=sensor, datasheet=datasheet, seed=seed,
                         instruments=getattr(rig_config, "instruments", None))
    parts: dict[str, Any] = {}
    versions = {f"sensor:{sensor.model}": sensor_version}
    config: dict[str, Any] = {}
    for kind in ("turntable", "daq", "chamber"):
        spec = getattr(rig_config, kind)
        parts[kind], versions[f"{kind}:{spec.plugin}"] = _construct(
            kind, spec.plugin, dict(spec.options), context
        )
        config[kind] = {"plugin": spec.plugin, **dict(spec.options)}
    instruments = getattr(rig_config, "instruments", None)
    if instruments is not None:  # the stated accuracies the uncertainty budgets read
        config["instruments"] = instruments.model_dump(mode="json")
    return Rig(parts["turntable"], parts["daq"], parts["chamber"], datasheet, context, versions,
               config)


def _safely(action: str, fn: Any) -> None:
    try:
        fn()
    except Exception as exc:  # noqa: BLE001 - a safe-state action must not mask the fault
        log.error("%s failed while reaching a safe state: %s", action, exc)


@contextmanager
def running(rig: Rig) -> Iterator[Rig]:
    """Start the rig; on any exit (fault, Ctrl-C, success) leave it safe and closed."""
    started: list[tuple[str, Any]] = []
    try:
        parts = (("chamber", rig.chamber), ("daq", rig.daq), ("turntable", rig.turntable))
        for name, part in parts:
            start = getattr(part, "start", None)
            try:
                if start is not None:
                    start()
            except AatestError:
                raise
            except Exception as exc:
                raise RigFault(f"{name} failed to start: {exc}") from exc
            started.append((name, part))
        yield rig
    finally:
        _safely("turntable.safe_stop", rig.turntable.safe_stop)
        _safely("chamber.off", rig.chamber.off)
        for _name, part in reversed(started):
            _safely(f"{_name}.close", part.close)
