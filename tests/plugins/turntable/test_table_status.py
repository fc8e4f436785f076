"""The optional live status (``Turntable.status()``) of the twin, Modbus and ACUTROL tables.

Each driver is read against its simulator and the readings are checked against the twin's
known motion: at rest the held position and zero rate; during a constant-rate step the
commanded rate and the position the rate has carried the table to at the controller's time.
The Modbus link is also read from another thread while a step records, as the run's status
poll does, and the step's log is the same as without the poll.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator

import numpy as np
import pytest

from aatest.engine.errors import RigFault
from aatest.engine.interfaces import RigContext, TableStatus, reports_status, table_status
from aatest.engine.logs import SampledLog
from aatest.engine.run.runner import execute_step as run_step
from aatest.engine.steps import PlannedStep, SensorRef
from aatest.plugins.sensors.sr207 import SR207
from aatest.plugins.turntable.acutrol import AcutrolTurntable
from aatest.plugins.turntable.sim import SimTurntable
from aatest.twin.model import RigModel
from aatest.twin.servers.acutrol_server import acutrol_server

RATE_DPS = 20.0
SETTLE_S = 2.0
RATE = PlannedStep(id="s01-rate", kind="constant_rate", axis="inner", rate_dps=RATE_DPS,
                   inner_deg=30.0, samples=4000, settle_s=SETTLE_S)
SINE = PlannedStep(id="s02-sine", kind="sine", axis="inner", frequency_hz=2.0, accel_dps2=100.0,
                   samples=4096, settle_s=2.0)
# RigModel() has no rate ripple and no motor vibration: the readings are the profile itself,
# exact in f64 positions and to the map's f32 for rates (relative 6e-8)
F32_REL = 1e-7


def _sim_table() -> SimTurntable:
    sheet = SR207().datasheet()
    context = RigContext(sensor=SensorRef(model="sr207"), datasheet=sheet, seed=5)
    return SimTurntable(SimTurntable.Config(), context)


def test_twin_table_reads_its_motion_at_the_lab_time() -> None:
    table = _sim_table()
    assert reports_status(table)
    table.start()
    table.move_to(30.0, 90.0)
    held = table_status(table)
    assert held is not None and held.clock == "controller"
    assert (held.inner_position_deg, held.outer_position_deg) == (30.0, 90.0)
    assert held.inner_rate_dps == held.outer_rate_dps == 0.0
    table.begin_motion(RATE)  # the profile starts at the lab time of the call and settles
    moving = table.status()
    assert moving.time_s == pytest.approx(held.time_s + SETTLE_S, abs=1e-9)
    # the realistic rig adds its motor line to the commanded motion: four tones of 3 °/s²
    # between 32 and 38 Hz, each at most 3/(2π·32) = 0.015 °/s in rate and 7.5e-5° in
    # position, and a 0.1″ position ripple at 1 and 2 cycles/° (< 0.01 °/s at 20 °/s)
    rate_bound_dps = 4 * 3.0 / (2 * np.pi * 32.0) + 0.01
    assert abs(moving.inner_rate_dps - RATE_DPS) < rate_bound_dps
    assert moving.inner_position_deg == pytest.approx(30.0 + RATE_DPS * SETTLE_S, abs=1e-3)
    assert abs(moving.outer_rate_dps or 0.0) < rate_bound_dps  # the outer axis holds at 90°
    assert moving.outer_position_deg == pytest.approx(90.0, abs=1e-3)
    table.end_motion()
    back = table.status()
    assert back.inner_position_deg == 30.0 and back.time_s > moving.time_s
    table.safe_stop()


def test_status_of_a_plugin_without_it_is_none_and_a_wrong_type_is_refused() -> None:
    class Legacy:
        pass

    class Wrong:
        def status(self) -> dict[str, float]:
            return {"time_s": 0.0}

    assert not reports_status(Legacy()) and table_status(Legacy()) is None
    with pytest.raises(Exception, match=r"status\(\) returned dict, expected TableStatus"):
        table_status(Wrong())


def test_a_reading_with_nan_is_refused() -> None:
    with pytest.raises(ValueError, match="finite"):
        TableStatus(time_s=0.0, clock="host", inner_position_deg=float("nan"),
                    inner_rate_dps=0.0)


def test_modbus_status_is_the_controllers_live_block(make_rig: Callable) -> None:
    rig = make_rig()
    rig.daq.start()
    rig.turntable.start()
    rig.turntable.move_to(30.0, 0.0)
    controller = rig.server.controller  # the test looks behind the wire for the twin's clock
    held = rig.turntable.status()
    assert held.clock == "controller" and held.time_s == controller.now_s()
    assert (held.inner_position_deg, held.inner_rate_dps) == (30.0, 0.0)
    rig.turntable.begin_motion(RATE)
    moving = rig.turntable.status()
    assert moving.time_s == pytest.approx(held.time_s + SETTLE_S, abs=1e-9)
    assert moving.inner_rate_dps == pytest.approx(RATE_DPS, rel=F32_REL)
    assert moving.inner_position_deg == pytest.approx(30.0 + RATE_DPS * SETTLE_S, abs=1e-9)
    assert moving.outer_rate_dps == 0.0


def test_modbus_status_polled_during_a_record_leaves_the_log_unchanged(
        make_rig: Callable) -> None:
    quiet, polled = make_rig(), make_rig()  # same seed: the same twin, the same logs
    for rig in (quiet, polled):
        rig.daq.start()
        rig.turntable.start()
    reference, _ = run_step(quiet, SINE)
    readings: list[TableStatus] = []
    stop = threading.Event()

    def poll() -> None:
        while not stop.is_set():
            readings.append(polled.turntable.status())

    poller = threading.Thread(target=poll)
    poller.start()
    try:
        table, _ = run_step(polled, SINE)
    finally:
        stop.set()
        poller.join(10)
    assert len(readings) > 10  # requests interleaved with the step's own on one link
    for channel in table.channels:
        np.testing.assert_array_equal(table[channel], reference[channel])
    times = [r.time_s for r in readings]
    assert times == sorted(times)  # the controller's clock never runs back
    # the sine's position amplitude α/(2πf)² = 0.633° bounds every reading (servo gain ≤ 1)
    amplitude = SINE.accel_dps2 / (2 * np.pi * SINE.frequency_hz) ** 2  # type: ignore[operator]
    assert max(abs(r.inner_position_deg) for r in readings) <= amplitude * 1.001


@pytest.fixture
def acutrol() -> Iterator[AcutrolTurntable]:
    with acutrol_server(model=RigModel()) as server:
        table = AcutrolTurntable(AcutrolTurntable.Config(port=server.port), None)
        table.start()
        yield table
        table.safe_stop()
        table.close()


def test_acutrol_status_reads_both_axes_in_one_line(acutrol: AcutrolTurntable) -> None:
    acutrol.move_to(10.5, 90.0)
    held = acutrol.status()
    assert held.clock == "host"
    # the replies carry 6 decimals
    assert (held.inner_position_deg, held.outer_position_deg) == (10.5, 90.0)
    assert held.inner_rate_dps == held.outer_rate_dps == 0.0
    acutrol.move_to(RATE.inner_deg, 0.0)
    acutrol.begin_motion(RATE)
    moving = acutrol.status()
    assert moving.inner_rate_dps == pytest.approx(RATE_DPS, abs=1e-6)
    assert moving.inner_position_deg == pytest.approx(30.0 + RATE_DPS * SETTLE_S, abs=1e-6)
    assert moving.time_s > held.time_s


def _acutrol_sine_log(poll: bool) -> tuple[SampledLog, list[TableStatus]]:
    """The table log of ``SINE`` from a fresh simulator (same seed), read with or without a
    thread asking for the status all along."""
    readings: list[TableStatus] = []
    with acutrol_server(model=RigModel(), seed=3) as server:
        table = AcutrolTurntable(AcutrolTurntable.Config(port=server.port), None)
        table.start()
        stop = threading.Event()

        def hammer() -> None:
            while poll and not stop.is_set():
                readings.append(table.status())

        poller = threading.Thread(target=hammer)
        poller.start()
        try:
            table.move_to(0.0, 0.0)
            table.begin_motion(SINE)
            server.protocol.controller.daq_start()  # type: ignore[attr-defined] # the trigger
            log = table.record(SINE)
            table.end_motion()
        finally:
            stop.set()
            poller.join(10)
            table.safe_stop()
            table.close()
    return log, readings


def test_acutrol_status_polled_during_a_record_leaves_the_log_unchanged() -> None:
    reference, _ = _acutrol_sine_log(poll=False)
    log, readings = _acutrol_sine_log(poll=True)
    assert len(readings) > 10  # status lines interleaved with the log's own queries
    for channel in log.channels:
        np.testing.assert_array_equal(log[channel], reference[channel])


def test_acutrol_status_of_a_closed_link_is_a_rig_fault(acutrol: AcutrolTurntable) -> None:
    acutrol.close()
    with pytest.raises(RigFault, match="not connected"):
        acutrol.status()
