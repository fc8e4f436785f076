"""No chamber: the sensor sits at lab ambient. Asking for another temperature is an error."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

from aatest.engine.errors import PluginError
from aatest.engine.interfaces import RigContext


class NoChamber:
    """The ambient "chamber" of a rig without one."""

    #: no chamber at all: nothing simulated (the room is real)
    simulated = False

    class Config(BaseModel):
        model_config = ConfigDict(extra="forbid")
        ambient_c: float = 22.0
        tolerance_c: float = Field(1.0, gt=0, description="set-points within this of ambient pass")

    def __init__(self, config: Config | None = None, context: RigContext | None = None) -> None:
        self.config = config if config is not None else self.Config()
        self.context = context

    def _ambient_c(self) -> float:
        """The twin's sensor temperature on a simulated rig, else the configured ambient."""
        from aatest.twin.session import TwinSession  # only to look it up; real rigs have none

        session = self.context.resources.get(TwinSession) if self.context is not None else None
        if session is None:
            return self.config.ambient_c
        return session.world.sensor_temperature_c()

    def set_temperature(self, setpoint_c: float) -> None:
        """Accept only the ambient set-point (the planner should never ask for another)."""
        ambient = self._ambient_c()
        if abs(setpoint_c - ambient) > self.config.tolerance_c:
            raise PluginError(f"chamber 'none': cannot reach {setpoint_c:g} °C, the rig has no "
                              f"chamber (ambient {ambient:g} °C); configure a chamber plugin")

    def wait_stable(self, soak_s: float) -> float:
        return self._ambient_c()

    def off(self) -> None:
        """Nothing to switch off."""

    def close(self) -> None:
        """Nothing to release."""
