"""The Modbus driver against the twin served over real Modbus TCP on loopback."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from aatest.engine.errors import RigFault
from aatest.engine.interfaces import AxisLimits, TableEnvelope
from aatest.engine.logs import TABLE_CHANNELS
from aatest.engine.run.runner import execute_step as run_step
from aatest.engine.steps import PlannedStep
from aatest.plugins.turntable.modbus import ModbusTurntable
from aatest.protocols.modbus_map import Status

SINE = PlannedStep(id="s01-sine", kind="sine", axis="inner", frequency_hz=2.0, accel_dps2=100.0,
                   samples=4096, settle_s=2.0)


def test_construction_does_not_connect() -> None:
    table = ModbusTurntable(ModbusTurntable.Config(port=1), None)
    assert table.envelope() == TableEnvelope()
    table.safe_stop()  # nothing to stop: no error
    table.close()


def test_sine_step_round_trip_is_physical(make_rig: Callable) -> None:
    rig = make_rig()
    rig.daq.start()
    rig.turntable.start()
    table, daq = run_step(rig, SINE)
    assert set(table.channels) == set(TABLE_CHANNELS) and len(table) == SINE.samples
    np.testing.assert_allclose(np.diff(table.time_s), 1 / 2000.0, rtol=1e-9)
    # commanded 100 °/s² peak at 2 Hz: position amplitude α/(2πf)² = 0.633 °
    amp = SINE.accel_dps2 / (2 * np.pi * SINE.frequency_hz) ** 2
    assert np.ptp(table["inner_position_deg"]) / 2 == pytest.approx(amp, rel=0.01)
    assert np.ptp(table["outer_position_deg"]) < 1e-3
    # the DAQ log comes from the same twin: it starts earlier, its trigger marks the record
    assert len(daq) > SINE.samples and set(np.unique(daq["trigger"])) == {0.0, 1.0}
    assert 0.3 < np.mean(table["sync_pulse"]) < 0.7
    # the served log is the twin's own log, bit for bit where the map uses f64
    twin = rig.server.controller._record.table  # test looks behind the wire
    np.testing.assert_array_equal(table["inner_position_deg"], twin["inner_position_deg"])
    np.testing.assert_allclose(table["inner_accel_dps2"], twin["inner_accel_dps2"], rtol=1e-7)


def test_controller_label_is_the_step_id(make_rig: Callable) -> None:
    rig = make_rig()
    rig.daq.start()
    rig.turntable.start()
    run_step(rig, SINE)
    assert rig.server.controller._label() == "s01-sine"


def test_refused_command_is_a_rig_fault(make_rig: Callable) -> None:
    rig = make_rig()
    rig.daq.start()
    rig.turntable.start()
    too_fast = SINE.model_copy(update={"accel_dps2": 5000.0})
    rig.turntable.move_to(0.0, 0.0)
    with pytest.raises(RigFault, match="START_MOTION refused: ACCEL_LIMIT"):
        rig.turntable.begin_motion(too_fast)


def test_declared_envelope_beyond_controller_limits_is_refused(make_rig: Callable) -> None:
    rig = make_rig()
    wide = TableEnvelope(inner=AxisLimits(rate_dps=5000.0, accel_dps2=1000.0))
    table = ModbusTurntable(ModbusTurntable.Config(port=rig.server.port, envelope=wide), None)
    with pytest.raises(RigFault, match="inner_rate_limit_dps 5000 exceeds"):
        table.start()
    table.close()


def test_safe_stop_switches_motor_off_and_is_idempotent(make_rig: Callable) -> None:
    rig = make_rig()
    rig.turntable.start()
    rig.turntable.move_to(10.0, 0.0)
    assert rig.server.controller.world.motor_on
    rig.turntable.safe_stop()
    rig.turntable.safe_stop()
    status = Status(rig.server.controller.read(1, 1)[0])
    assert Status.MOTOR_ON not in status and Status.MOVING not in status


def test_controller_enforces_the_declared_envelope(make_rig: Callable) -> None:
    rig = make_rig()
    narrow = TableEnvelope(inner=AxisLimits(rate_dps=1200.0, accel_dps2=80.0))
    table = ModbusTurntable(ModbusTurntable.Config(port=rig.server.port, envelope=narrow), None)
    table.start()
    table.move_to(0.0, 0.0)
    with pytest.raises(RigFault, match="START_MOTION refused: ACCEL_LIMIT"):
        table.begin_motion(SINE)  # 100 °/s² > the declared 80 °/s²: the controller refuses
    table.safe_stop()
    table.close()


def test_static_step_with_the_motor_off_is_held_without_the_servo(make_rig: Callable) -> None:
    """``motor_on: false`` reaches the controller as the simulated table honours it: the
    step's truth has the motor off (no servo jitter on the sensor: the twin's table adds its
    motor vibration only with the motor on), and the motor is on again for the next move."""
    rig = make_rig()
    rig.daq.start()
    rig.turntable.start()
    world = rig.server.controller.world  # test looks behind the wire
    still = PlannedStep(id="s01-off", kind="static", samples=4096, settle_s=0.5, motor_on=False)
    rig.turntable.move_to(0.0, 0.0)
    rig.turntable.begin_motion(still)
    assert world._motion[1].motor_on is False and world._motion[2].motor_on is False
    rig.turntable.end_motion()
    assert world.motor_on and Status.MOTOR_ON in rig.turntable._status()
    table, _ = run_step(rig, still)  # a whole record with the motor off
    assert len(table) == still.samples and world.motor_on
