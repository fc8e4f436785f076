"""A single-axis rate table: a vendor turntable plugin with its own envelope.

The table has one continuous axis (aatest's *inner* axis) and no outer axis: its envelope says
so (outer travel pinned at 0°), so the planner refuses any procedure that tilts or excites the
outer axis before anything moves. The motion itself is simulated here by the aatest twin
(shared with the simulated DAQ through ``RigContext.resources``), with the table model's limits
set from this table's datasheet; a real vendor driver would talk to its controller instead.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

from aatest.engine.errors import EnvelopeRefused, RigFault
from aatest.engine.interfaces import AxisLimits, RigContext, TableEnvelope
from aatest.engine.logs import SampledLog
from aatest.engine.steps import PlannedStep

#: a locked axis: no travel and (pydantic needs > 0) a vanishing rate/acceleration allowance
_LOCKED = AxisLimits(rate_dps=1e-9, accel_dps2=1e-9, continuous=False, min_deg=0.0, max_deg=0.0)


class SingleAxisTable:
    """ACME SR-1 single-axis rate table (inner axis only)."""

    class Config(BaseModel):
        """Limits of this table (datasheet values by default)."""

        model_config = ConfigDict(extra="forbid")
        rate_limit_dps: float = Field(720.0, gt=0)
        accel_limit_dps2: float = Field(1500.0, gt=0)
        max_frequency_hz: float = Field(20.0, gt=0)
        log_rate_hz: float = Field(2000.0, gt=0)

    def __init__(self, config: Config | None, context: RigContext) -> None:
        self.config = config if config is not None else self.Config()
        self.context = context
        self._twin = self._session()

    def envelope(self) -> TableEnvelope:
        cfg = self.config
        return TableEnvelope(inner=AxisLimits(rate_dps=cfg.rate_limit_dps,
                                              accel_dps2=cfg.accel_limit_dps2),
                             outer=_LOCKED, max_log_rate_hz=cfg.log_rate_hz,
                             max_frequency_hz=cfg.max_frequency_hz)

    def _session(self):  # noqa: ANN202 - the twin's TwinSession (aatest.twin), imported lazily
        """Share the twin, built with this table's limits, before the simulated DAQ asks."""
        from aatest.twin.defaults import realistic_rig_model
        from aatest.twin.session import TwinSession, twin_session

        context = self.context
        if context is not None and context.resources.get(TwinSession) is None:
            model = realistic_rig_model(context.datasheet)
            inner = model.table.inner.model_copy(update={
                "rate_limit_dps": self.config.rate_limit_dps,
                "accel_limit_dps2": self.config.accel_limit_dps2})
            model = model.model_copy(update={"table": model.table.model_copy(
                update={"inner": inner, "log_rate_hz": self.config.log_rate_hz})})
            context.resources.setdefault(
                TwinSession, lambda: TwinSession(context.datasheet, context.seed, model))
        return twin_session(context)

    def _world(self):  # noqa: ANN202 - the twin's World
        return self._twin.world

    def start(self) -> None:
        self._world().motor_on = True

    def move_to(self, inner_deg: float, outer_deg: float) -> None:
        if outer_deg != 0.0:
            raise EnvelopeRefused(f"single-axis table: no outer axis (asked for {outer_deg:g}°)")
        if not self._world().motor_on:
            raise RigFault("single-axis table: move_to with the motor off")
        self._world().move_to(inner_deg, 0.0)

    def begin_motion(self, step: PlannedStep) -> None:
        if step.axis in ("outer", "both") or step.outer_rate_dps:
            raise EnvelopeRefused(f"step {step.id}: the single-axis table has no outer axis")
        self._world().begin_motion(step)

    def record(self, step: PlannedStep) -> SampledLog:
        return self._world().result().table

    def end_motion(self) -> None:
        self._world().end_motion()

    def safe_stop(self) -> None:
        """Stop and switch the motor off; never raises."""
        try:
            world = self._world()
            world.end_motion()
            world.motor_on = False
        except Exception:  # noqa: BLE001 - a safe stop must never raise
            pass

    def close(self) -> None:
        self.safe_stop()
