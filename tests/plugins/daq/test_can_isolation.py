"""Two CAN runs on one host stay apart: udp_multicast groups on one port, session tags on one bus.

python-can's udp_multicast binds every group to the same port (43113); on Linux a socket bound
so receives every group joined by any socket on the host unless ``IP_MULTICAST_ALL`` is off.
"""

from __future__ import annotations

import os
import sys
import threading
import time
from collections.abc import Iterator

import numpy as np
import pytest
from test_can import STEP, Feeder, daq_log

from aatest.engine.errors import RigFault
from aatest.engine.logs import SampledLog
from aatest.plugins.daq.can import CanDaq
from aatest.protocols import can_frames as cf
from aatest.protocols.can_bus import open_bus, send
from aatest.twin.servers.can_sim import SimCanLogger


def _groups() -> tuple[str, str]:
    """Two groups of this test process (concurrent test processes pick others)."""
    octet = 10 + os.getpid() % 200
    return f"239.74.{octet}.11", f"239.74.{octet}.12"


def _drain(bus: object, quiet_s: float = 0.3) -> list[int]:
    ids: list[int] = []
    while (msg := bus.recv(quiet_s)) is not None:  # type: ignore[attr-defined]
        ids.append(msg.arbitration_id)
    return ids


def test_a_udp_bus_hears_only_its_own_group() -> None:
    pytest.importorskip("msgpack", reason="python-can's udp_multicast needs msgpack")
    if sys.platform != "linux":
        pytest.skip("IP_MULTICAST_ALL is a Linux option")
    group_a, group_b = _groups()
    buses = {g: open_bus("udp_multicast", g) for g in (group_a, group_b)}
    listener_a = open_bus("udp_multicast", group_a)
    try:
        for _i in range(30):
            send(buses[group_b], 0x181, bytes(8), True, "group b")
        for _i in range(7):
            send(buses[group_a], 0x182, bytes(8), True, "group a")
        ids = _drain(listener_a)
    finally:
        for bus in (*buses.values(), listener_a):
            bus.shutdown()
    assert ids.count(0x181) == 0  # foreign frames (the old code received all 30)
    assert ids.count(0x182) == 7  # own frames all arrive


class _Pair:
    """A simulated logger and its CanDaq on one udp_multicast group, fed one known record."""

    def __init__(self, group: str, seed: int) -> None:
        self.record = daq_log(n=1500, seed=seed)
        self.logger = SimCanLogger(Feeder(self.record), "udp_multicast", group).start()
        self.daq = CanDaq(CanDaq.Config(interface="udp_multicast", channel=group,
                                        channels=["v_sz", "v_sy"], response_timeout_s=2.0,
                                        frame_timeout_s=2.0), None)
        self.got: SampledLog | None = None
        self.error: BaseException | None = None

    def run(self, barrier: threading.Barrier) -> None:
        try:
            self.daq.start()
            barrier.wait(10.0)
            self.daq.start_logging(STEP)
            time.sleep(0.3)  # the paced stream (1500 frames at 10 kHz) is running
            self.got = self.daq.stop_logging()
        except BaseException as exc:  # noqa: BLE001 - reported by the test thread
            self.error = exc

    def close(self) -> None:
        self.daq.close()
        self.logger.stop()


@pytest.fixture
def two_pairs() -> Iterator[tuple[_Pair, _Pair]]:
    pytest.importorskip("msgpack", reason="python-can's udp_multicast needs msgpack")
    if sys.platform != "linux":
        pytest.skip("IP_MULTICAST_ALL is a Linux option")
    group_a, group_b = _groups()
    pairs = (_Pair(group_a, seed=1), _Pair(group_b, seed=2))
    yield pairs
    for pair in pairs:
        pair.close()


def test_two_concurrent_logger_pairs_each_record_only_their_own(
        two_pairs: tuple[_Pair, _Pair]) -> None:
    barrier = threading.Barrier(2)
    threads = [threading.Thread(target=p.run, args=(barrier,)) for p in two_pairs]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(30.0)
    for pair in two_pairs:
        assert pair.error is None, pair.error
        assert pair.got is not None
        # exactly the own record's frames: no foreign frame added, none lost
        assert len(pair.got) == len(pair.record)
        np.testing.assert_allclose(pair.got["v_sz"], pair.record["v_sz"], rtol=1.2e-7)
        np.testing.assert_allclose(pair.got.time_s, pair.record.time_s, atol=0.6e-9, rtol=0)
    # the two records differ (seeds 1 and 2), so the comparison above can tell them apart
    assert not np.allclose(two_pairs[0].record["v_sz"], two_pairs[1].record["v_sz"])


class _V1Logger(SimCanLogger):
    """A logger of frame layout version 1: ignores the command's session, never tags."""

    def _command(self, opcode: int, session: int) -> None:
        super()._command(opcode, cf.NO_SESSION)


def _virtual_daq(channel: str) -> CanDaq:
    daq = CanDaq(CanDaq.Config(channel=channel, channels=["v_sz", "v_sy"],
                               response_timeout_s=0.5, frame_timeout_s=0.5), None)
    daq.start()
    return daq


def test_a_second_host_on_one_bus_neither_records_nor_disturbs_the_first() -> None:
    """Host B shares host A's bus and logger: B's START during A's stream is refused by the
    logger, A records exactly its own record, and B counts A's frames as foreign."""
    channel = f"can-iso-{os.getpid()}"
    record = daq_log(n=3000, seed=3)
    logger = SimCanLogger(Feeder(record), "virtual", channel, frame_rate_hz=2000.0).start()
    # B opens second: its PING re-tags the idle logger to session b
    host_a, host_b = _virtual_daq(channel), _virtual_daq(channel)
    try:
        assert host_a.session != host_b.session
        host_a.start_logging(STEP)
        time.sleep(0.1)  # A's 1.5 s stream is running
        with pytest.raises(RigFault, match="no acknowledgement of START"):
            host_b.start_logging(STEP)
        got = host_a.stop_logging()
    finally:
        for part in (host_a, host_b):
            part.close()
        logger.stop()
    assert logger.foreign_commands == 1
    assert len(got) == len(record) and not host_a.gaps
    np.testing.assert_allclose(got["v_sz"], record["v_sz"], rtol=1.2e-7)
    assert host_a.foreign_frames == 1  # the IDLE answer to B's PING
    assert host_b.foreign_frames >= len(record)  # all of A's samples, its STATUS answers


def test_an_untagged_version_1_logger_is_still_recorded() -> None:
    channel = f"can-v1-{os.getpid()}"
    record = daq_log(n=500, seed=4)
    logger = _V1Logger(Feeder(record), "virtual", channel).start()
    daq = _virtual_daq(channel)
    try:
        daq.start_logging(STEP)
        got = daq.stop_logging()
    finally:
        daq.close()
        logger.stop()
    assert len(got) == len(record)
    np.testing.assert_allclose(got["v_sz"], record["v_sz"], rtol=1.2e-7)


def test_frames_carry_the_session_tag() -> None:
    record = daq_log(n=3)
    volts = np.column_stack([record["v_sz"], record["v_sy"]])
    payloads = cf.encode_samples(record.time_s, volts, record["sync_pulse"], record["trigger"],
                                 record["temperature_c"], session=0xBEEF)
    assert {cf.sample_session(p) for p in payloads} == {0xBEEF}
    assert cf.command_session(cf.command_payload(cf.Opcode.START, 0xBEEF)) == 0xBEEF
    status = cf.parse_status(cf.status_payload(cf.LoggerState.END_OF_RECORD, 7, session=0xBEEF))
    assert (status.state, status.frames_sent, status.session) == (
        cf.LoggerState.END_OF_RECORD, 7, 0xBEEF)
