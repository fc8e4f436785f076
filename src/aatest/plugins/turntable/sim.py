"""The simulated two-axis turntable: the twin's controller, driven in virtual lab time.

Construction moves nothing; ``start`` powers the motor on. Every motion command is checked
against the axis limits *in the controller* (independent of the planner) and refused with
:class:`~aatest.engine.errors.EnvelopeRefused` when it exceeds them, as the real controller does.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict

from aatest.engine.errors import EnvelopeRefused, RigFault
from aatest.engine.interfaces import (
    AxisLimits,
    RigContext,
    TableCapabilities,
    TableEnvelope,
    TableStatus,
)
from aatest.engine.logs import SampledLog
from aatest.engine.steps import PlannedStep
from aatest.plugin_options import RigFilePath
from aatest.twin.session import twin_session
from aatest.twin.world import World


class SimTurntable:
    """Turntable plugin backed by the shared :class:`~aatest.twin.world.World`."""

    #: the digital twin: a run on it is a simulation, never a calibration
    simulated = True

    class Config(BaseModel):
        """Options: ``model`` = path of a rig-model YAML (default: the realistic SR207 rig).

        ``inner_limits``/``outer_limits`` replace an axis's limits of the rig model: the
        controller enforces their rate (°/s) and acceleration (°/s²), the envelope reports them
        whole (travel too). A host plugin wraps the twin this way as a table of other limits.
        """

        model_config = ConfigDict(extra="forbid")
        model: RigFilePath | None = None
        serial: str = "digital-twin"
        inner_limits: AxisLimits | None = None
        outer_limits: AxisLimits | None = None

    def __init__(self, config: Config, context: RigContext) -> None:
        self.config = config
        self.context = context
        self._twin = twin_session(context, config.model)
        self._twin.table_driven = True

    @property
    def serial(self) -> str:
        """Identifies the table on certificates (traceability)."""
        return self.config.serial

    def capabilities(self) -> TableCapabilities:
        """What the twin's table has: its encoder's count, trigger input and pulse latch.

        The encoder *accuracy* is not declared: the twin's encoder error is whatever its rig
        model draws, which a budget must not take as a measured bound (the rig description's
        ``instruments.encoder`` states it).
        """
        counts = round(360.0 / self.world.model.table.inner.encoder_resolution_deg)
        return TableCapabilities(encoder_resolution_counts_per_rev=counts, trigger_input=True,
                                 pulse_latch=True, model="aatest digital twin, two-axis",
                                 serial=self.config.serial)

    @property
    def world(self) -> World:
        """The shared twin, its controller held to the configured axis limits."""
        world = self._twin.world
        limits = {"inner": self.config.inner_limits, "outer": self.config.outer_limits}
        table = world.model.table
        update = {axis: getattr(table, axis).model_copy(update={
            "rate_limit_dps": lim.rate_dps, "accel_limit_dps2": lim.accel_dps2})
            for axis, lim in limits.items() if lim is not None}
        if update:
            world.model = world.model.model_copy(update={"table": table.model_copy(update=update)})
        return world

    def envelope(self) -> TableEnvelope:
        """The limits the controller enforces (configured, else from the rig model)."""
        table = self.world.model.table
        return TableEnvelope(
            inner=self.config.inner_limits or AxisLimits(
                rate_dps=table.inner.rate_limit_dps, accel_dps2=table.inner.accel_limit_dps2),
            outer=self.config.outer_limits or AxisLimits(
                rate_dps=table.outer.rate_limit_dps, accel_dps2=table.outer.accel_limit_dps2),
            max_log_rate_hz=table.log_rate_hz, log_capacity_samples=table.log_capacity_samples)

    def start(self) -> None:
        """Clear faults and switch the motor on."""
        self.world.motor_on = True

    def move_to(self, inner_deg: float, outer_deg: float) -> None:
        if not self.world.motor_on:
            raise RigFault("simulated turntable: move_to with the motor off (call start first)")
        self.world.move_to(inner_deg, outer_deg)

    def begin_motion(self, step: PlannedStep) -> None:
        """Start the step's profile (refused beyond limits) and settle."""
        table = self.world.model.table
        if step.sample_rate_hz > table.log_rate_hz * (1 + 1e-12):
            raise EnvelopeRefused(f"step {step.id}: log rate {step.sample_rate_hz:g} Hz exceeds "
                                  f"the controller's {table.log_rate_hz:g} Hz")
        if step.samples > table.log_capacity_samples and step.kind != "static":
            raise EnvelopeRefused(f"step {step.id}: {step.samples} samples exceed the log "
                                  f"capacity of {table.log_capacity_samples}")
        if not self.world.motor_on:
            raise RigFault("simulated turntable: begin_motion with the motor off")
        self.world.begin_motion(step)

    def record(self, step: PlannedStep) -> SampledLog:
        """The table log of ``step``, started by the DAQ trigger (at rest during a long
        record: the periodic snapshots the runner asks for, within the log capacity)."""
        table = self.world.model.table
        if step.samples > table.log_capacity_samples:
            raise EnvelopeRefused(f"step {step.id}: {step.samples} samples exceed the log "
                                  f"capacity of {table.log_capacity_samples}")
        return self.world.table_record(step)

    def end_motion(self) -> None:
        self.world.end_motion()

    def status(self) -> TableStatus:
        """The twin's table now: its motion state at the current lab time (the controller
        clock of the twin). Only reads the shared twin (it may run in another thread)."""
        world = self._twin.built_world
        if world is None:
            raise RigFault("simulated turntable: status read before the twin was built")
        now = world.table_state()
        return TableStatus(time_s=now.time_s, clock="controller",
                           inner_position_deg=now.inner_deg, inner_rate_dps=now.inner_dps,
                           outer_position_deg=now.outer_deg, outer_rate_dps=now.outer_dps)

    def safe_stop(self) -> None:
        """Stop motion and switch the motor off; never raises."""
        try:
            world = self._twin.built_world
            if world is not None:
                world.end_motion()
                world.motor_on = False
        except Exception:  # noqa: BLE001 - a safe stop must never raise
            pass

    def close(self) -> None:
        self.safe_stop()
