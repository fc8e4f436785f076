"""Building the rig from plugin names and owning its life cycle.

The engine, not the plugins, decides when a rig starts and stops: if one plugin fails to start,
the ones whose start was called (the failing one too) are brought to a safe state and closed,
and the error names the plugin that failed. Any fault while running ends in ``safe_stop`` (table
stopped, motor off). A rig that is only built (to read its envelope) is never started, stopped
or closed.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from aatest.engine import registry
from aatest.engine.errors import AatestError, PluginError, RigFault
from aatest.engine.interfaces import Chamber, Daq, RigContext, SensorDatasheet, Turntable
from aatest.engine.steps import SensorRef
from aatest.metrology.verdicts_limits import datasheet_from_info
from aatest.recording.dataset import SensorInfo

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

    def simulated_parts(self) -> list[str]:
        """``KIND:PLUGIN`` of every part declaring ``simulated = True`` (drivers of a simulator
        server know it only once started). Any such part makes the run a simulation."""
        return [f"{kind}:{self.config[kind]['plugin']}" for kind in ("turntable", "daq", "chamber")
                if getattr(getattr(self, kind), "simulated", False) is True]


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


def datasheets(metadata: Mapping[str, Any], sensors: Sequence[SensorInfo]
               ) -> dict[str, SensorDatasheet]:
    """Each channel's datasheet: the recorded sensor model's plugin, else the channel's values.

    A recording names its sensor model (``metadata["sensor"]``), whose plugin states every
    limit; imported data states its datasheet values per channel in ``dataset.yaml``.
    """
    sensor = metadata.get("sensor")
    if isinstance(sensor, Mapping) and sensor.get("model"):
        sheet, source = sensor_datasheet(SensorRef.model_validate(dict(sensor)))
        log.debug("acceptance limits from the datasheet of %s (%s)", sensor["model"], source)
        # the recorded nominals are the datasheet's; the channel list is the recording's
        return {info.channel: sheet for info in sensors} or dict.fromkeys(sheet.channels, sheet)
    return {info.channel: datasheet_from_info(info) for info in sensors}


def _construct(kind: str, name: str, options: dict[str, Any], context: RigContext,
               rig_dir: Path | None) -> tuple[Any, str]:
    info = registry.load(kind, name)
    config = registry.configure(info, options, rig_dir)
    try:
        plugin = info.target(config, context)
    except AatestError:
        raise
    except Exception as exc:
        raise PluginError(f"{kind} plugin {name!r} ({info.distribution}) failed: {exc}") from exc
    return plugin, f"{info.distribution} {info.version}"


def build_rig(rig_config: Any, sensor: SensorRef, seed: int) -> Rig:
    """Construct turntable, DAQ and chamber plugins; nothing is connected or moved yet.

    Plugins connect in ``start`` (:func:`running`), never in their constructors, so building a
    rig to read its envelope (``validate``, ``plan``) sends the hardware nothing.
    """
    datasheet, sensor_version = sensor_datasheet(sensor)
    context = RigContext(sensor=sensor, datasheet=datasheet, seed=seed,
                         instruments=getattr(rig_config, "instruments", None))
    parts: dict[str, Any] = {}
    versions = {f"sensor:{sensor.model}": sensor_version}
    config: dict[str, Any] = {}
    for kind in ("turntable", "daq", "chamber"):
        spec = getattr(rig_config, kind)
        parts[kind], versions[f"{kind}:{spec.plugin}"] = _construct(
            kind, spec.plugin, dict(spec.options), context, getattr(rig_config, "rig_dir", None))
        config[kind] = {"plugin": spec.plugin, **dict(spec.options)}
    instruments = getattr(rig_config, "instruments", None)
    if instruments is not None:  # the stated accuracies the uncertainty budgets read
        # only what the rig file states: a budget row tells a stated value from a declared or
        # a default one (docs/vendor-plugins.md, "Capabilities")
        config["instruments"] = instruments.model_dump(mode="json", exclude_unset=True)
    return Rig(parts["turntable"], parts["daq"], parts["chamber"], datasheet, context, versions,
               config)


def _safely(action: str, fn: Any) -> None:
    try:
        fn()
    except Exception as exc:  # noqa: BLE001 - a safe-state action must not mask the fault
        log.error("%s failed while reaching a safe state: %s", action, exc)


@contextmanager
def running(rig: Rig) -> Iterator[Rig]:
    """Start the rig; on any exit (fault, Ctrl-C, success) leave it safe and closed.

    Only plugins whose ``start`` was called are touched afterwards: the turntable gets
    ``safe_stop`` and the chamber ``off`` only once their ``start`` was called (even when it
    raised: a half-done start may have switched a motor on), then every such plugin is closed,
    in reverse order. A plugin never started gets no call at all, so a rig whose chamber fails
    to start never talks to its turntable.
    """
    attempted: list[tuple[str, Any]] = []
    try:
        parts = (("chamber", rig.chamber), ("daq", rig.daq), ("turntable", rig.turntable))
        for name, part in parts:
            attempted.append((name, part))
            start = getattr(part, "start", None)
            try:
                if start is not None:
                    start()
            except AatestError:
                raise
            except Exception as exc:
                raise RigFault(f"{name} failed to start: {exc}") from exc
        yield rig
    finally:
        touched = dict(attempted)
        if "turntable" in touched:
            _safely("turntable.safe_stop", rig.turntable.safe_stop)
        if "chamber" in touched:
            _safely("chamber.off", rig.chamber.off)
        for name, part in reversed(attempted):
            _safely(f"{name}.close", part.close)
