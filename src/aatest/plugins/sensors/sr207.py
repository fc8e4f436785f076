"""SR207-class servo force-balance fluid-rotor angular accelerometer (docs/method.md §1.3).

``SR207`` is one sensor (channel ``v_sz`` on the inner axis); ``SR207Unit`` the three-sensor
measurement unit (AAMU) with S_Z on I, S_Y on O and S_X on P (docs/method.md §4.5).

The SR207 is aatest's reference sensor: its datasheet numbers are the defaults of
:class:`~aatest.engine.datasheet.SensorDatasheet`, stated once in :mod:`aatest.engine.datasheet`,
so this plugin only names the model and its channels. How such a sensor really behaves (its
dynamics, drift, hysteresis) is the twin's knowledge (:mod:`aatest.twin.defaults`), built from
this datasheet; the plugin knows nothing of the twin.
"""

from __future__ import annotations

from typing import Any, ClassVar

from pydantic import BaseModel, ConfigDict

from aatest.engine.datasheet import SensorAxis, SensorDatasheet


class _Sensor:
    """Common plugin behaviour; subclasses set the model name and the channel map."""

    channels_map: ClassVar[dict[str, SensorAxis]] = {"v_sz": "I"}
    plugin_name: ClassVar[str] = "sr207"

    class Config(BaseModel):
        model_config = ConfigDict(extra="forbid")

    def __init__(self, config: BaseModel | None = None, context: Any = None) -> None:
        self.config = config if config is not None else self.Config()
        self.context = context

    def datasheet(self) -> SensorDatasheet:
        """Datasheet values of docs/method.md §1.3 (the reference defaults) for this layout."""
        return SensorDatasheet(model=self.plugin_name, channels=dict(self.channels_map))


class SR207(_Sensor):
    """A single SR207 on the inner axis (channel ``v_sz``)."""

    class Config(BaseModel):
        model_config = ConfigDict(extra="forbid")


class SR207Unit(_Sensor):
    """Three SR207 on a mounting block: S_Z on I, S_Y on O, S_X on P."""

    channels_map: ClassVar[dict[str, SensorAxis]] = {"v_sz": "I", "v_sy": "O", "v_sx": "P"}
    plugin_name: ClassVar[str] = "sr207-aamu"

    class Config(BaseModel):
        model_config = ConfigDict(extra="forbid")
