"""The simulated rig plugins driven through the runner's call sequence (virtual lab time)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydantic import ValidationError
from twin_steps import sine_step, static_step

from aatest.engine.errors import EnvelopeRefused, PluginError, RigFault
from aatest.engine.interfaces import Chamber, Daq, RigContext, SensorDatasheet, Turntable
from aatest.engine.logs import TABLE_CHANNELS
from aatest.engine.steps import Mounting, PlannedStep, SensorRef
from aatest.plugins.chamber.none import NoChamber
from aatest.plugins.chamber.sim import SimChamber
from aatest.plugins.daq.sim import SimDaq
from aatest.plugins.sensors.sr207 import SR207, SR207Unit
from aatest.plugins.turntable.sim import SimTurntable
from aatest.twin.api import nominal_rig_model
from aatest.twin.model import dump_rig_model
from aatest.twin.session import TwinSession


def _rig(model: str = "sr207-aamu", seed: int = 7, **table_opts: object):
    sensor = SR207Unit() if model == "sr207-aamu" else SR207()
    ctx = RigContext(sensor=SensorRef(model=model), datasheet=sensor.datasheet(), seed=seed)
    table = SimTurntable(SimTurntable.Config(**table_opts), ctx)
    daq = SimDaq(SimDaq.Config(), ctx)
    chamber = SimChamber(SimChamber.Config(), ctx)
    return ctx, table, daq, chamber


def _record(table: SimTurntable, daq: SimDaq, step: PlannedStep):
    table.move_to(step.inner_deg, step.outer_deg)
    table.begin_motion(step)
    daq.start_logging(step)
    tlog = table.record(step)
    dlog = daq.stop_logging()
    table.end_motion()
    return tlog, dlog


def test_plugins_satisfy_protocols_and_share_one_world() -> None:
    _, table, daq, chamber = _rig()
    assert isinstance(table, Turntable) and isinstance(daq, Daq) and isinstance(chamber, Chamber)
    assert table.world is daq.world is chamber.world
    assert list(daq.channels())[:3] == ["v_sz", "v_sy", "v_sx"]
    assert table.envelope().inner.accel_dps2 == 1000.0 and table.envelope().outer.rate_dps == 500.0


def test_construction_moves_nothing_and_start_powers_on() -> None:
    _, table, _, _ = _rig()
    assert table.world.lab_time_s == 0.0 and not table.world.motor_on
    with pytest.raises(RigFault):
        table.move_to(10.0, 0.0)
    table.start()
    table.move_to(10.0, 0.0)
    assert table.world.inner_deg == 10.0 and table.world.lab_time_s > 0.0


def test_runner_sequence_records_both_logs_in_virtual_time() -> None:
    _, table, daq, _ = _rig()
    table.start()
    step = sine_step(1.0, 100.0, samples=8192)
    t_before = table.world.lab_time_s
    tlog, dlog = _record(table, daq, step)
    assert set(tlog.channels) == set(TABLE_CHANNELS) and len(tlog) == 8192
    assert len(dlog) > len(tlog)
    assert table.world.lab_time_s - t_before > step.settle_s + step.duration_s
    # the table log sees a 100 °/s² sine on the inner axis
    omega = 2 * np.pi * step.frequency_hz
    amplitude_deg = np.std(tlog["inner_position_deg"]) * np.sqrt(2)
    assert_allclose(amplitude_deg * omega**2, 100.0, rtol=0.02)


@pytest.mark.parametrize(("axis", "accel"), [("inner", 1200.0), ("outer", 250.0)],
                         ids=["inner", "outer"])
def test_controller_refuses_commands_beyond_limits(axis: str, accel: float) -> None:
    _, table, _, _ = _rig()
    table.start()
    with pytest.raises(EnvelopeRefused, match="acceleration"):
        table.begin_motion(sine_step(1.0, accel, samples=1024, axis=axis))
    with pytest.raises(EnvelopeRefused, match="capacity"):
        table.begin_motion(sine_step(1.0, 10.0, samples=300_000, axis=axis))
    # a long static record is streamed by the DAQ; only a full-rate table log of it is refused
    table.begin_motion(static_step(samples=300_000))
    with pytest.raises(EnvelopeRefused, match="capacity"):
        table.record(static_step(samples=300_000))


def test_safe_stop_is_idempotent_and_never_raises() -> None:
    _, table, _, _ = _rig()
    table.safe_stop()
    table.start()
    table.safe_stop()
    table.safe_stop()
    assert not table.world.motor_on


def test_sim_chamber_waits_for_the_thermal_lag() -> None:
    _, table, _, chamber = _rig()
    chamber.set_temperature(-21.0)
    reached = chamber.wait_stable(900.0)
    tau = table.world.model.chamber.sensor_time_constant_s
    assert abs(reached + 21.0) <= table.world.model.chamber.stable_band_c + 1e-9
    # 43 °C step to within 0.2 °C needs τ·ln(43/0.2) ≈ 5.4 τ > 15 min
    assert_allclose(table.world.lab_time_s, tau * np.log(43.0 / 0.2), rtol=1e-9)


def test_no_chamber_refuses_non_ambient_setpoints() -> None:
    chamber = NoChamber()
    chamber.set_temperature(22.3)
    assert chamber.wait_stable(10.0) == 22.0
    with pytest.raises(PluginError, match="no chamber"):
        chamber.set_temperature(-20.0)


def test_model_file_option_loads_the_rig_model(tmp_path: Path) -> None:
    path = tmp_path / "rig.yaml"
    dump_rig_model(nominal_rig_model(), path)
    _, table, daq, _ = _rig_with_file(path)
    table.start()
    _, dlog = _record(table, daq, static_step(samples=1024))
    assert np.std(dlog["v_sz"]) < 1e-6  # nominal model: no noise, no vibration
    assert_allclose(dlog["v_sz"], 2.5, atol=1e-6)


def _rig_with_file(path: Path):
    ctx = RigContext(sensor=SensorRef(model="sr207"), datasheet=SensorDatasheet(model="sr207"))
    daq = SimDaq(SimDaq.Config(), ctx)  # built first: the World is rebuilt from the file later
    table = SimTurntable(SimTurntable.Config(model=str(path)), ctx)
    return ctx, table, daq, None


def test_pivot_flips_cross_axis_response() -> None:
    """Outer excitation at inner 0° is along +y of S_Z; pivoting flips the sign of its pick-up."""
    _, table, daq, _ = _rig(seed=3)
    table.start()
    base = sine_step(1.0, 100.0, samples=4096, axis="outer")
    piv = base.model_copy(update={"id": "piv", "mounting": Mounting(pivoted=True)})
    w = table.world
    axes_o = w.sensor_axes()["v_sz"].copy()
    _record(table, daq, piv)
    axes_p = w.sensor_axes()["v_sz"]
    # in the seat's frame (block and seat errors undone) the sensor turns 180° about z:
    # x and y turn over, and the sensitive axis' lean (internal misalignment) flips with them
    from aatest.twin.kinematics import SEAT_FRAMES

    seat = w.block_error @ SEAT_FRAMES["I"] @ w.seat_error["v_sz"]
    assert_allclose(seat.T @ axes_p, np.diag([-1.0, -1.0, 1.0]) @ (seat.T @ axes_o), atol=1e-12)
    assert abs((seat.T @ axes_o)[0, 2]) > 1e-3  # the internal misalignment is there to flip


def test_sensor_plugins() -> None:
    assert SR207().datasheet().channels == {"v_sz": "I"}
    unit = SR207Unit(SR207Unit.Config(), None).datasheet()
    assert unit.channels == {"v_sz": "I", "v_sy": "O", "v_sx": "P"}
    assert SR207().datasheet().scale_v_per_dps2 == pytest.approx(0.23 * np.pi / 180, rel=1e-3)
    with pytest.raises(ValidationError, match="unknown"):
        SR207.Config(unknown=1)  # type: ignore[call-arg]


def test_plugins_share_one_typed_twin_session() -> None:
    ctx, table, daq, chamber = _rig()
    session = ctx.resources.get(TwinSession)
    assert session is not None and session.world is table.world is daq.world is chamber.world
    assert session.seed == ctx.seed and session.datasheet is ctx.datasheet


def test_plugins_naming_different_model_files_are_a_configuration_error(tmp_path: Path) -> None:
    first, second = tmp_path / "a.yaml", tmp_path / "b.yaml"
    for path in (first, second):
        dump_rig_model(nominal_rig_model(), path)
    ctx = RigContext(sensor=SensorRef(model="sr207"), datasheet=SensorDatasheet(model="sr207"))
    SimTurntable(SimTurntable.Config(model=str(first)), ctx)
    SimChamber(SimChamber.Config(model=str(first)), ctx)  # the same file: fine
    with pytest.raises(PluginError, match="disagree about the rig model"):
        SimDaq(SimDaq.Config(model=str(second)), ctx)


def test_the_twin_simulates_the_datasheet_it_is_handed() -> None:
    sheet = SensorDatasheet(model="acme", range_dps2=2000.0, nominal_scale_v_per_dps2=0.001,
                            channels={"v_a": "I", "v_b": "P"})
    ctx = RigContext(sensor=SensorRef(model="acme"), datasheet=sheet, seed=2)
    table, daq = SimTurntable(SimTurntable.Config(), ctx), SimDaq(SimDaq.Config(), ctx)
    assert list(daq.channels())[:2] == ["v_a", "v_b"]
    assert [(s.scale_v_per_dps2, s.range_dps2) for s in table.world.model.sensors] == [
        (0.001, 2000.0)] * 2
