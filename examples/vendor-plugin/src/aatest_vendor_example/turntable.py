"""A single-axis rate table: a vendor turntable plugin with its own envelope.

The ACME SR-1 has one continuous axis (aatest's *inner* axis) and no outer axis. Its envelope
says so (outer travel pinned at 0°), so the planner refuses any procedure that tilts or excites
the outer axis before anything moves, and the table refuses such commands itself as well.

This example has no hardware to talk to: it moves by delegating every command to the turntable
simulator that ships with aatest, loaded by name through the plugin registry (``"sim"``) and
configured with this table's limits, so the simulated controller enforces exactly the envelope
declared here. A real driver keeps the same methods and talks to its controller instead (see
aatest's ``modbus`` turntable). Only aatest's public plugin API is used.
"""

from __future__ import annotations

import logging

from pydantic import BaseModel, ConfigDict, Field

from aatest.engine import registry
from aatest.engine.errors import EnvelopeRefused
from aatest.engine.interfaces import AxisLimits, RigContext, TableEnvelope, Turntable
from aatest.engine.logs import SampledLog
from aatest.engine.steps import PlannedStep

log = logging.getLogger(__name__)

#: the installed turntable plugin that simulates this table's motion
SIMULATOR = "sim"

#: the missing outer axis: no travel and (limits must be > 0) a vanishing rate/acceleration
NO_AXIS = AxisLimits(rate_dps=1e-9, accel_dps2=1e-9, continuous=False, min_deg=0.0, max_deg=0.0)


class SingleAxisTable:
    """ACME SR-1 single-axis rate table (inner axis only), simulated by aatest's ``sim`` table.

    Parameters
    ----------
    config
        This table's options (``None``: the datasheet values).
    context
        The rig context the engine hands every rig plugin; passed on to the simulator, which
        shares the digital twin with the simulated DAQ through it.
    """

    #: this example moves aatest's simulator, not a table: its runs are simulations (a real
    #: driver declares ``simulated = False``, or sets it from the controller's identification)
    simulated = True

    class Config(BaseModel):
        """Limits of this table (datasheet values by default) and its serial number."""

        model_config = ConfigDict(extra="forbid")
        rate_limit_dps: float = Field(720.0, gt=0, description="axis rate limit, °/s")
        accel_limit_dps2: float = Field(1500.0, gt=0, description="axis acceleration limit, °/s²")
        max_frequency_hz: float = Field(20.0, gt=0, description="usable terminal frequency, Hz")
        log_rate_hz: float = Field(2000.0, gt=0, description="table log sample rate, Hz")
        serial: str = "SR1-0042"

    def __init__(self, config: Config | None, context: RigContext) -> None:
        self.config = config if config is not None else self.Config()
        envelope = self.envelope()
        simulator = registry.load("turntable", SIMULATOR)
        options = {"serial": self.config.serial, "inner_limits": envelope.inner.model_dump(),
                   "outer_limits": envelope.outer.model_dump()}
        self._controller: Turntable = simulator.target(
            registry.configure(simulator, options), context)

    @property
    def serial(self) -> str:
        """Identifies the table on certificates (traceability)."""
        return self.config.serial

    def envelope(self) -> TableEnvelope:
        """What the SR-1 can do: one axis with the configured limits, no outer axis."""
        cfg = self.config
        return TableEnvelope(
            inner=AxisLimits(rate_dps=cfg.rate_limit_dps, accel_dps2=cfg.accel_limit_dps2),
            outer=NO_AXIS, max_log_rate_hz=cfg.log_rate_hz, max_frequency_hz=cfg.max_frequency_hz)

    def start(self) -> None:
        """Connect, clear faults and switch the motor on."""
        self._controller.start()

    def move_to(self, inner_deg: float, outer_deg: float) -> None:
        """Position the axis; any outer angle but 0° is refused."""
        if outer_deg != 0.0:
            raise EnvelopeRefused(f"ACME SR-1: no outer axis (asked for {outer_deg:g}°)")
        self._controller.move_to(inner_deg, 0.0)

    def begin_motion(self, step: PlannedStep) -> None:
        """Start the step's profile; steps that move the outer axis are refused."""
        if step.axis in ("outer", "both") or step.outer_rate_dps:
            raise EnvelopeRefused(f"step {step.id}: the ACME SR-1 has no outer axis")
        self._controller.begin_motion(step)

    def record(self, step: PlannedStep) -> SampledLog:
        """The table log of ``step`` (exactly the table channels, on the table clock)."""
        return self._controller.record(step)

    def end_motion(self) -> None:
        """Bring the axis to rest."""
        self._controller.end_motion()

    def safe_stop(self) -> None:
        """Stop and switch the motor off; never raises, may be called twice."""
        try:
            self._controller.safe_stop()
        except Exception as exc:  # noqa: BLE001 - a safe stop must never raise
            log.error("ACME SR-1: safe stop failed: %s", exc)

    def close(self) -> None:
        """Leave the table safe and release it."""
        self.safe_stop()
        self._controller.close()
