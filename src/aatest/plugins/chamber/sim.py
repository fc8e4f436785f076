"""The simulated temperature chamber: set-point steps, sensor thermal lag, stabilisation."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict

from aatest.engine.errors import RigFault
from aatest.engine.interfaces import RigContext, Stability
from aatest.plugin_options import RigFilePath
from aatest.twin.session import twin_session
from aatest.twin.world import World


class SimChamber:
    """Chamber plugin backed by the shared World (virtual lab time, no sleeping)."""

    #: the digital twin: a run on it is a simulation, never a calibration
    simulated = True

    class Config(BaseModel):
        model_config = ConfigDict(extra="forbid")
        model: RigFilePath | None = None

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

    def wait_until_stable(self, tolerance_c: float, window_s: float, max_s: float) -> Stability:
        """Advance lab time until the sensor temperature's spread over ``window_s`` is within
        ``tolerance_c`` (:class:`~aatest.engine.interfaces.StableChamber`)."""
        temperature_c, spread_c, waited_s = self.world.wait_until_stable(tolerance_c, window_s,
                                                                         max_s)
        if spread_c > tolerance_c * (1 + 1e-9):  # solved to the tolerance, so not to bits
            raise RigFault(f"chamber sim: not stable within {max_s:g} s: the sensor temperature "
                           f"spread {spread_c:.3g} °C over {window_s:g} s (tolerance "
                           f"{tolerance_c:g} °C)")
        return Stability(temperature_c, spread_c, window_s, tolerance_c, waited_s)

    def off(self) -> None:
        """Switch the chamber off: the sensor keeps its temperature for the short record."""

    def close(self) -> None:
        """Nothing to release."""
