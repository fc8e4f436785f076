"""The simulated on-table sensor logger: its own crystal clock, sensors, sync pulse, trigger."""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence

from pydantic import BaseModel, ConfigDict

from aatest.engine.interfaces import RigContext
from aatest.engine.logs import DAQ_AUX_CHANNELS, SampledLog
from aatest.engine.steps import PlannedStep
from aatest.plugin_options import RigFilePath
from aatest.twin.defaults import SLIP_RING_RMS_V
from aatest.twin.model import ExcessNoise
from aatest.twin.session import twin_session
from aatest.twin.synthesis import GENERATION_BLOCK
from aatest.twin.world import World


class SimDaq:
    """DAQ plugin backed by the shared World."""

    #: the digital twin: a run on it is a simulation, never a calibration
    simulated = True

    class Config(BaseModel):
        """``slip_ring``: route the sensors through the slip ring instead of the on-table logger."""

        model_config = ConfigDict(extra="forbid")
        model: RigFilePath | None = None
        slip_ring: bool = False

    def __init__(self, config: Config, context: RigContext) -> None:
        self.config = config
        self.context = context
        self._twin = twin_session(context, config.model)
        self._route_signals()

    def _route_signals(self) -> None:
        """Put the slip ring in the sensor path when configured (idempotent)."""
        world = self.world
        if self.config.slip_ring and world.model.daq.slip_ring is None:
            ring = ExcessNoise(rms_v=SLIP_RING_RMS_V)
            daq = world.model.daq.model_copy(update={"slip_ring": ring})
            world.model = world.model.model_copy(update={"daq": daq})

    @property
    def world(self) -> World:
        return self._twin.world

    def channels(self) -> Sequence[str]:
        return [s.channel for s in self.world.model.sensors] + list(DAQ_AUX_CHANNELS)

    def cannot_follow(self, turntable: object) -> str | None:
        """Why this logger cannot record beside ``turntable`` (None: it can).

        It records the sensors of the digital twin, which moves only when a simulated table
        drives it (``sim``, or a vendor plugin wrapping it): beside any other table its
        records would start without motion, so such a rig is refused at ``validate``.
        """
        if self._twin.table_driven:
            return None
        return (f"the simulated DAQ records the digital twin's sensors and follows only a "
                f"table that moves the twin (turntable 'sim' or a plugin wrapping it); "
                f"{type(turntable).__name__} does not — use the logger of that table "
                "(e.g. daq 'can')")

    def start(self) -> None:
        """Nothing to connect: the simulated logger is always ready."""

    def start_logging(self, step: PlannedStep) -> None:
        """Start logging now; the trigger follows ``start_lead_s`` later."""
        self._route_signals()
        self.world.start_daq()

    def stop_logging(self) -> SampledLog:
        """Stop (``stop_lag_s`` after the table log) and return the DAQ log."""
        return self.world.result().daq

    def stream_logging(self, step: PlannedStep, chunk_s: float) -> Iterator[SampledLog]:
        """Start logging now and yield the record in chunks of whole generation blocks
        (≥ ``chunk_s`` lab seconds of samples; the last one shorter), generated lazily with
        continuous noise, filter and drift state: the same samples as one-shot logging of
        the same long record."""
        self._route_signals()
        self.world.start_daq()
        per_chunk = max(1, math.ceil(chunk_s * step.sample_rate_hz / GENERATION_BLOCK))
        yield from self.world.stream_daq(per_chunk)

    def close(self) -> None:
        """Nothing to release."""
