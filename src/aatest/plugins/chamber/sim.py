"""The simulated temperature chamber: set-point steps, sensor thermal lag, stabilisation."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict

from aatest.engine.interfaces import RigContext
from aatest.twin.session import twin_session
from aatest.twin.world import World


class SimChamber:
    """Chamber plugin backed by the shared World (virtual lab time, no sleeping)."""

    #: the digital twin: a run on it is a simulation, never a calibration
    simulated = True

    class Config(BaseModel):
        model_config = ConfigDict(extra="forbid")
        model: str | None = None

    def __init__(self, config: Config, context: RigContext) -> None:
        self.config = config
        self.context = context
        self._twin = twin_session(context, config.model)

    @property
    def world(self) -> World:
        return self._twin.world

    def set_temperature(self, setpoint_c: float) -> None:
        self.world.set_temperature(setpoint_c)

    def wait_stable(self, soak_s: float) -> float:
        """Advance lab time until soaked and within the stable band; return the sensor °C."""
        return self.world.wait_stable(soak_s)

    def off(self) -> None:
        """Switch the chamber off: the sensor keeps its temperature for the short record."""

    def close(self) -> None:
        """Nothing to release."""
