"""The twin session: the one :class:`~aatest.twin.world.World` the simulated plugins of a rig share.

The first simulated plugin of a rig creates the session in the rig's typed shared resources
(``RigContext.resources``, keyed by the :class:`TwinSession` class), the others find it there;
nothing is looked up by a string key. The session builds its World lazily, on first use, from
the rig-model file a plugin was configured with, else from the twin's realistic defaults for
the sensor datasheet the engine resolved (``RigContext.datasheet``). Two plugins naming
different model files is a configuration error.
"""

from __future__ import annotations

from pathlib import Path

from aatest.engine.datasheet import SensorDatasheet
from aatest.engine.errors import PluginError
from aatest.engine.interfaces import RigContext
from aatest.engine.rig_description import Instruments
from aatest.engine.steps import SensorRef
from aatest.twin.defaults import realistic_rig_model
from aatest.twin.model import RigModel, load_rig_model
from aatest.twin.world import World

__all__ = ["TwinSession", "twin_session"]


class TwinSession:
    """The shared twin of one simulated rig and the model file it is built from.

    Parameters
    ----------
    datasheet
        The sensor's datasheet; without a model file the twin simulates one realistic sensor
        per datasheet channel (:func:`aatest.twin.defaults.realistic_rig_model`).
    seed
        Seed of every random draw of the World.
    model
        An explicit rig model (e.g. a vendor table that sets its own limits); a model file
        named by a plugin still takes precedence.
    imperfections_seed
        When given, the World is built from the model with its instrument errors drawn within
        ``instruments`` (:meth:`aatest.twin.model.RigModel.draw_imperfections`); None (the
        default) keeps the model exactly as stated, deterministic.
    instruments
        The stated specifications the imperfections are drawn within (default: the
        documented rig's).
    """

    def __init__(self, datasheet: SensorDatasheet, seed: int = 0,
                 model: RigModel | None = None, imperfections_seed: int | None = None,
                 instruments: Instruments | None = None) -> None:
        self.datasheet = datasheet
        self.seed = int(seed)
        self.model = model
        self.imperfections_seed = imperfections_seed
        self.instruments = instruments
        self.model_path: str | None = None
        #: a simulated turntable moves this twin (the simulated DAQ can only follow such a one)
        self.table_driven = False
        self._world: World | None = None

    def claim(self, model_path: str | None) -> None:
        """Note the model file a plugin was configured with (None or empty: no preference).

        Raises
        ------
        PluginError
            Another plugin of this rig already named a different model file.
        """
        if not model_path:
            return
        if self.model_path is None:
            self.model_path = model_path
            self._world = None  # built before any plugin named a model file: nothing ran yet
        elif self.model_path != model_path:
            raise PluginError(f"sim plugins disagree about the rig model: {model_path!r} vs "
                              f"{self.model_path!r}")

    @property
    def world(self) -> World:
        """The shared World, built on first use."""
        if self._world is None:
            if self.model_path:
                model = load_rig_model(self.model_path)
            else:
                model = self.model if self.model is not None else realistic_rig_model(
                    self.datasheet)
            if self.instruments is not None and (
                    not self.model_path or "logger" in self.instruments.model_fields_set):
                # a stated logger is the twin's logger (the rig description is the one source,
                # which the rail verdict and the budget read): over a model file's converter
                # too; the defaults only where no model file states one
                model = model.model_copy(update={
                    "daq": model.daq.with_logger(self.instruments.logger)})
            if self.imperfections_seed is not None:
                model = model.draw_imperfections(self.imperfections_seed, self.instruments)
            self._world = World(model, self.seed)
        return self._world

    @property
    def built_world(self) -> World | None:
        """The World if one was built, else None (a safe stop must not build one)."""
        return self._world


def twin_session(context: RigContext | None, model_path: str | Path | None = None
                 ) -> TwinSession:
    """The twin session of this rig, created by the first simulated plugin that asks.

    Parameters
    ----------
    context
        The rig context the engine handed the plugin; None (a plugin built on its own, e.g.
        in a test) gives a private session for the reference sensor.
    model_path
        The rig-model YAML the asking plugin was configured with, if any (a relative one
        already resolved against the rig file, :data:`aatest.plugin_options.RigFilePath`).
    """
    if context is None:
        context = RigContext(sensor=SensorRef(model="reference"),
                             datasheet=SensorDatasheet(model="reference"))
    rig = context
    session = rig.resources.setdefault(TwinSession, lambda: TwinSession(
        rig.datasheet, rig.seed, instruments=rig.instruments))
    session.claim(str(model_path) if model_path else None)
    return session
