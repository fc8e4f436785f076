"""The CAN logger path with N sensors: the frames carry every channel of a three-sensor unit, and
a logger serving another number of sensors than the plugin expects is named, not mis-decoded."""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterator

import numpy as np
import pytest

from aatest.engine.errors import RigFault
from aatest.engine.logs import DAQ, DAQ_AUX_CHANNELS, SampledLog
from aatest.engine.steps import PlannedStep
from aatest.plugins.daq.can import CanDaq
from aatest.plugins.sensors.sr207 import SR207Unit
from aatest.protocols import can_frames as cf
from aatest.twin.defaults import realistic_rig_model
from aatest.twin.servers.can_sim import SimCanLogger
from aatest.twin.world import World

UNIT = ("v_sz", "v_sy", "v_sx")
_names = itertools.count()


def unit_record(samples: int = 1200) -> SampledLog:
    """One static record of the twin's three-sensor unit (seeded), as its logger produces it."""
    world = World(realistic_rig_model(SR207Unit().datasheet()), seed=3)
    world.motor_on = True
    world.begin_motion(PlannedStep(id="s", kind="static", samples=samples))
    world.start_daq()
    return world.result().daq


class _Feeder:
    """Stands in for the simulated controller: the DAQ start emits the prepared record."""

    def __init__(self, record: SampledLog) -> None:
        self.record = record
        self.on_daq_log: Callable[[SampledLog], None] | None = None

    def daq_start(self) -> None:
        if self.on_daq_log is not None:
            self.on_daq_log(self.record)


@pytest.fixture
def logger_of() -> Iterator[Callable[[SampledLog, list[str]], CanDaq]]:
    parts: list[CanDaq | SimCanLogger] = []

    def make(record: SampledLog, channels: list[str]) -> CanDaq:
        channel = f"can-n-{next(_names)}"
        parts.append(SimCanLogger(_Feeder(record), "virtual", channel).start())
        daq = CanDaq(CanDaq.Config(channel=channel, channels=channels,
                                   response_timeout_s=1.0, frame_timeout_s=0.5), None)
        parts.append(daq)
        daq.start()
        return daq

    yield make
    for part in parts:
        part.close() if isinstance(part, CanDaq) else part.stop()


def test_three_sensor_record_crosses_the_bus_channel_by_channel(logger_of: Callable) -> None:
    record = unit_record()
    assert tuple(record.sensor_channels()) == UNIT
    daq = logger_of(record, list(UNIT))
    daq.start_logging(PlannedStep(id="s", kind="static", samples=len(record)))
    got = daq.stop_logging()
    for channel in UNIT:  # f32 volts on the wire: relative 6e-8, < 0.3 µV at 2.5 V
        np.testing.assert_allclose(got[channel], record[channel], rtol=1.2e-7)
    # three different sensors, not one copied: their means differ by ≥ 0.77 mV (own bias
    # offsets and g terms), the difference of two 1200-sample means of 1 mV noise has
    # σ ≈ 41 µV, so 0.3 mV is > 7σ from equal
    means = [float(np.mean(got[c])) for c in UNIT]
    assert min(abs(a - b) for a, b in itertools.combinations(means, 2)) > 3e-4


def test_frames_of_one_sensor_read_as_three_are_a_named_error() -> None:
    assert cf.SAMPLE_HEADER.fields is not None
    assert cf.SAMPLE_HEADER.fields["n_channels"][1] == cf.N_CHANNELS_BYTE  # the byte checked
    record = unit_record(100)
    one = cf.encode_samples(record.time_s, record["v_sz"], record["sync_pulse"],
                            record["trigger"], record["temperature_c"])
    with pytest.raises(ValueError, match="sample frames carry 1 voltage channels, expected 3"):
        cf.decode_samples(one, 3)
    with pytest.raises(ValueError, match=r"must be 32 bytes long; received lengths \[20, 32\]"):
        cf.decode_samples([*cf.encode_samples(
            record.time_s[:2], np.column_stack([record[c][:2] for c in UNIT]),
            record["sync_pulse"][:2], record["trigger"][:2], record["temperature_c"][:2]),
            one[0]], 3)


def test_logger_serving_fewer_sensors_is_a_rig_fault_naming_the_channels(
        logger_of: Callable) -> None:
    record = unit_record(200)
    kept = ("v_sz", *DAQ_AUX_CHANNELS)  # the logger of a single sensor
    single = SampledLog(DAQ, record.sample_rate_hz, record.time_s,
                        {c: record[c] for c in kept}, {c: record.units[c] for c in kept})
    daq = logger_of(single, list(UNIT))
    daq.start_logging(PlannedStep(id="s", kind="static", samples=200))
    with pytest.raises(RigFault, match=r"carry 1 voltage channels, expected 3 \(v_sz, v_sy, "
                                       r"v_sx\); check 'channels' and the sensors"):
        daq.stop_logging()
