"""The twin a simulator in its own process serves: the realistic rig carrying a named sensor.

Shared by ``aatest sim-server acutrol`` and ``aatest sim-server modbus`` (``--sensor MODEL``),
so both build the rig the in-process twin builds from the procedure's ``sensor.model``.
"""

from __future__ import annotations

from aatest.twin.model import RigModel


def sensor_rig_model(sensor: str | None) -> RigModel:
    """The twin's realistic rig carrying the sensors of the sensor plugin ``sensor``.

    The in-process twin builds its rig from the datasheet of the procedure's ``sensor.model``
    (:class:`~aatest.twin.session.TwinSession`); a simulator in its own process is told the
    model by its operator (``--sensor``) and builds the same one realistic sensor per datasheet
    channel, so its CAN logger serves every channel of the unit. None: the reference sensor
    (one channel ``v_sz``).

    Raises
    ------
    PluginError
        No installed sensor plugin has that name.
    """
    from aatest.twin.defaults import realistic_rig_model

    if sensor is None:
        return realistic_rig_model()
    from aatest.engine.run.rig import sensor_datasheet
    from aatest.engine.steps import SensorRef

    return realistic_rig_model(sensor_datasheet(SensorRef(model=sensor))[0])
