"""A single-axis rate table: a vendor turntable plugin with its own envelope.

The ACME SR-1 has one continuous axis (aatest's *inner* axis) and no outer axis. Its envelope
says so (``axes: [inner]``), so the planner refuses any procedure that tilts or excites the
outer axis before anything moves, and the table refuses such commands itself as well. Its
capabilities declare its 24-bit encoder (0.077″ per count), which the uncertainty budget then
uses instead of a default, its trigger input and freeze-pulse latch, and — once ``start`` has
identified the controller — its model and serial number.

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
from aatest.engine.interfaces import (
    AxisLimits,
    RigContext,
    TableCapabilities,
    TableEnvelope,
    Turntable,
)
from aatest.engine.logs import SampledLog
from aatest.engine.steps import PlannedStep

log = logging.getLogger(__name__)

#: the installed turntable plugin that simulates this table's motion
SIMULATOR = "sim"

#: what the *simulator* is told of the missing outer axis (it has no notion of an absent
#: axis): no travel, a vanishing rate and acceleration. The envelope declares the axis absent.
SIMULATED_NO_AXIS = AxisLimits(rate_dps=1e-9, accel_dps2=1e-9, continuous=False, min_deg=0.0,
                               max_deg=0.0)
#: the SR-1's encoder: 24 bits per revolution, 0.077″ per count
ENCODER_COUNTS_PER_REV = 2**24


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
        encoder_accuracy_arcsec: float = Field(2.0, ge=0,
                                               description="encoder accuracy bound, arcsec")
        serial: str = Field("SR1-0042", description="what the simulated controller reports "
                            "as its serial number when identified")

    #: this example moves the twin, not hardware (the conformance kit checks it says so)
    simulated = True

    def __init__(self, config: Config | None, context: RigContext) -> None:
        # construction connects nothing: validate and plan build the table only to read its
        # envelope and capabilities
        self.config = config if config is not None else self.Config()
        simulator = registry.load("turntable", SIMULATOR)
        options = {"serial": self.config.serial,
                   "inner_limits": self.envelope().inner.model_dump(),
                   "outer_limits": SIMULATED_NO_AXIS.model_dump()}
        self._controller: Turntable = simulator.target(
            registry.configure(simulator, options), context)
        self._identified: str | None = None

    def envelope(self) -> TableEnvelope:
        """What the SR-1 can do: one axis with the configured limits, no outer axis."""
        cfg = self.config
        return TableEnvelope(
            inner=AxisLimits(rate_dps=cfg.rate_limit_dps, accel_dps2=cfg.accel_limit_dps2),
            axes=("inner",), max_log_rate_hz=cfg.log_rate_hz,
            max_frequency_hz=cfg.max_frequency_hz)

    def capabilities(self) -> TableCapabilities:
        """The SR-1's instruments; its serial only once :meth:`start` has identified it."""
        return TableCapabilities(
            encoder_resolution_counts_per_rev=ENCODER_COUNTS_PER_REV,
            encoder_accuracy_arcsec=self.config.encoder_accuracy_arcsec,
            trigger_input=True, pulse_latch=True, model="ACME SR-1", serial=self._identified)

    def start(self) -> None:
        """Connect, identify the controller, clear faults and switch the motor on."""
        self._controller.start()
        self._identified = self.config.serial  # a real driver reads it from the controller

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
        """Release the table (the engine calls ``safe_stop`` first, and ``close`` only after
        ``start``: a rig built to read the envelope is never closed)."""
        self._controller.close()
