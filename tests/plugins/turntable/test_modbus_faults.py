"""Fault injection in the simulated controller: each fault is a one-line RigFault (exit 3),
and the table ends in a safe state."""

from __future__ import annotations

import socket
import time
from collections.abc import Callable

import pytest

from aatest.engine.errors import EXIT_RIG_FAULT, RigFault
from aatest.engine.steps import PlannedStep
from aatest.plugins.turntable.modbus import ModbusTurntable
from aatest.protocols.modbus_map import Command, Fault, Status
from aatest.twin.servers.modbus_controller import FaultInjection

STEP = PlannedStep(id="s01", kind="sine", axis="inner", frequency_hz=1.0, accel_dps2=50.0,
                   samples=2048, settle_s=1.0)


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _one_line(exc: pytest.ExceptionInfo[RigFault]) -> str:
    message = str(exc.value)
    assert "\n" not in message and exc.value.exit_code == EXIT_RIG_FAULT
    return message


def test_connection_refused() -> None:
    table = ModbusTurntable(ModbusTurntable.Config(port=_free_port(), timeout_s=0.3), None)
    with pytest.raises(RigFault) as exc:
        table.start()
    assert "cannot connect" in _one_line(exc)
    table.safe_stop()
    table.close()


def test_timeout_on_slow_controller(make_rig: Callable) -> None:
    rig = make_rig(faults=FaultInjection(response_delay_s=0.5), timeout_s=0.2)
    started = time.monotonic()
    with pytest.raises(RigFault) as exc:
        rig.turntable.start()
    assert "no answer to read MAP_VERSION within 0.2 s" in _one_line(exc)
    assert time.monotonic() - started < 5.0


def _arm_for_record(rig) -> None:  # the test rig of conftest
    """Everything the runner does before ``record``: start, move, begin motion, start DAQ."""
    rig.daq.start()
    rig.turntable.start()
    rig.turntable.move_to(0.0, 0.0)
    rig.turntable.begin_motion(STEP)
    rig.daq.start_logging(STEP)


def test_controller_stops_answering_mid_step(make_rig: Callable) -> None:
    rig = make_rig(faults=FaultInjection(hang_on_command=Command.ARM_LOG, hang_s=3.0),
                   timeout_s=0.3)
    _arm_for_record(rig)
    with pytest.raises(RigFault) as exc:
        rig.turntable.record(STEP)
    assert "no answer to command ARM_LOG" in _one_line(exc)
    started = time.monotonic()
    rig.turntable.safe_stop()  # cannot be confirmed, must not raise, bounded in time
    rig.turntable.safe_stop()
    assert time.monotonic() - started < 3.0


def test_fault_bit_during_record_stops_the_table(make_rig: Callable) -> None:
    rig = make_rig(faults=FaultInjection(fault_on_record=Fault.INTERLOCK_OPEN))
    _arm_for_record(rig)
    with pytest.raises(RigFault) as exc:
        rig.turntable.record(STEP)
    assert "controller fault (fault bits INTERLOCK_OPEN, word 0x0002)" in _one_line(exc)
    rig.turntable.safe_stop()
    status = Status(rig.server.controller.read(1, 1)[0])
    assert Status.MOTOR_ON not in status and Status.MOVING not in status
    assert Status.FAULT in status


def test_fault_is_cleared_by_a_fresh_start(make_rig: Callable) -> None:
    rig = make_rig(faults=FaultInjection(fault_on_record=Fault.SERVO_ERROR))
    _arm_for_record(rig)
    with pytest.raises(RigFault):
        rig.turntable.record(STEP)
    rig.turntable.safe_stop()
    rig.daq.stop_logging()  # the logger still ends its (empty) record cleanly
    rig.server.controller.faults.fault_on_record = Fault(0)  # the operator fixed the rig
    rig.turntable.close()
    rig.turntable.start()  # start clears faults and switches the motor on again
    rig.turntable.move_to(0.0, 0.0)
    rig.turntable.begin_motion(STEP)
    rig.daq.start_logging(STEP)
    assert len(rig.turntable.record(STEP)) == STEP.samples
