"""The SR-1's conformance rig for aatest's kit (``pytest --aatest-plugin
turntable:acme-single-axis``): the table is simulated by aatest's twin, shared through the
rig context; its one fault is a servo trip (the motor switches off by itself mid-run)."""

from __future__ import annotations

from aatest.engine.datasheet import SensorDatasheet
from aatest.engine.interfaces import RigContext
from aatest.engine.steps import SensorRef
from aatest.testing.conformance import ConformanceRig
from aatest.twin.session import twin_session
from aatest.twin.world import World


def rig() -> ConformanceRig:
    """The SR-1 on the twin; the kit starts the DAQ where a DAQ plugin would."""
    context = RigContext(sensor=SensorRef(model="reference"),
                         datasheet=SensorDatasheet(model="reference"))

    def world() -> World:  # the twin is built on first use by the table itself
        return twin_session(context).world

    def servo_trip() -> None:
        world().motor_on = False

    return ConformanceRig(
        options={}, context=context, faults={"servo-trip": servo_trip}, recover=lambda: None,
        is_safe=lambda: not world().motor_on, close=lambda: None,
        trigger=lambda: world().start_daq(), fault_timeout_s=5.0)
