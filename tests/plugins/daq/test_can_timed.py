"""Timed CAN records (issue 31 item 7): the logger ends the record itself and streams it in
chunks; the plugin accounts for every frame chunk by chunk, on the virtual python-can bus.

The transcripts are what a bus monitor shows: the host's TIMED_START, the logger's STATUS
frames (logging, CHUNK marks with the frames sent so far, end of record or FAULT) and the
number of sample frames between them.
"""

from __future__ import annotations

import itertools
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import can
import numpy as np
import pytest
from typer.testing import CliRunner

from aatest.cli import app
from aatest.engine.errors import RigFault
from aatest.engine.interfaces import StreamingDaq, supports_streaming
from aatest.engine.logs import DAQ, DAQ_AUX_CHANNELS, SampledLog
from aatest.engine.steps import PlannedStep
from aatest.plugins.daq.can import CanDaq
from aatest.protocols import can_frames as cf
from aatest.twin.servers.can_sim import CHUNK_MARK_FRAMES, CanFaultInjection, SimCanLogger
from aatest.twin.synthesis import concatenate_logs

FS_HZ = 2000.0
#: a record of 3 logger blocks of 10 000 frames (the twin's generation blocks, smaller)
BLOCK, BLOCKS = 10_000, 3
TOTAL = BLOCK * BLOCKS
STEP = PlannedStep(id="s-long", kind="static", samples=TOTAL - 1000)
_names = itertools.count()


def record(n: int = TOTAL, seed: int = 3) -> SampledLog:
    """A DAQ record as the logger produces it: 2 kHz clock, 100 Hz pulse, trigger step."""
    rng = np.random.default_rng(seed)
    time_s = np.arange(n) / FS_HZ - 0.35
    data = {ch: 2.5 + rng.normal(0, 1e-3, n) for ch in ("v_sz", "v_sy")}
    data["sync_pulse"] = (np.arange(n) // 10 % 2).astype(float)
    data["trigger"] = (np.arange(n) >= 700).astype(float)
    data["temperature_c"] = np.round(22.0 + 1e-5 * np.arange(n), 2)
    return SampledLog(DAQ, FS_HZ, time_s, data, {"v_sz": "V", "v_sy": "V"} | DAQ_AUX_CHANNELS)


def part(log: SampledLog, start: int, stop: int) -> SampledLog:
    """Samples ``start:stop`` of a log (one block the simulated controller hands on)."""
    return SampledLog(log.source, log.sample_rate_hz, log.time_s[start:stop],
                      {k: v[start:stop] for k, v in log.channels.items()}, dict(log.units))


class StreamingFeeder:
    """Stands in for the simulated controller: a timed record yields the prepared record in
    blocks (lazily, as the World does); ``asked`` holds the lengths the logger asked for."""

    def __init__(self, full: SampledLog | None, refuse: bool = False) -> None:
        self.full, self.refuse = full, refuse
        self.asked: list[int] = []
        self.on_daq_log: Callable[[SampledLog], None] | None = None

    def daq_start(self) -> None:
        """The one-shot path is not used here."""

    def daq_stream(self, samples: int) -> Iterator[SampledLog]:
        self.asked.append(samples)
        if self.refuse or self.full is None:
            raise ValueError("a record already runs")
        full = self.full
        return (part(full, i, i + BLOCK) for i in range(0, len(full), BLOCK))


class Monitor(can.Listener):
    """A bus monitor: (what, detail) per command and STATUS frame, sample frames counted."""

    def __init__(self) -> None:
        self.lines: list[tuple[str, int]] = []
        self._samples = 0
        self._lock = threading.Lock()

    def on_message_received(self, msg: can.Message) -> None:
        with self._lock:
            if cf.SAMPLE_BASE < msg.arbitration_id < cf.SAMPLE_BASE + 16:
                self._samples += 1
                return
            if self._samples:
                self.lines.append(("samples", self._samples))
                self._samples = 0
            if cf.COMMAND_BASE < msg.arbitration_id < cf.COMMAND_BASE + 16:
                opcode = cf.Opcode(msg.data[0])
                detail = cf.command_samples(msg.data) if opcode == cf.Opcode.TIMED_START else 0
                self.lines.append((opcode.name, detail))
            elif cf.STATUS_BASE < msg.arbitration_id < cf.STATUS_BASE + 16:
                status = cf.parse_status(msg.data)
                self.lines.append((status.state.name, status.frames_sent))


@pytest.fixture
def timed_pair() -> Iterator[Callable[..., tuple[CanDaq, StreamingFeeder, Monitor]]]:
    parts: list[Any] = []

    def make(faults: CanFaultInjection | None = None, feeder: StreamingFeeder | None = None,
             frame_rate_hz: float | None = None,
             **config: object) -> tuple[CanDaq, StreamingFeeder, Monitor]:
        channel = f"can-timed-{next(_names)}"
        feeder = feeder or StreamingFeeder(record())
        logger = SimCanLogger(feeder, "virtual", channel, frame_rate_hz=frame_rate_hz,
                              faults=faults).start()
        monitor = Monitor()
        bus = can.Bus(interface="virtual", channel=channel, fd=True)
        notifier = can.Notifier(bus, [monitor], timeout=0.05)
        daq = CanDaq(CanDaq.Config(channel=channel, channels=["v_sz", "v_sy"],
                                   response_timeout_s=1.0, frame_timeout_s=1.0, **config), None)
        parts.extend([daq, logger, notifier, bus])
        daq.start()
        return daq, feeder, monitor

    yield make
    for part in parts:
        getattr(part, "close", getattr(part, "stop", getattr(part, "shutdown", None)))()


def _collect(daq: CanDaq, chunk_s: float = 6.0) -> tuple[list[SampledLog], RigFault | None]:
    """The chunks yielded until the end, and the fault that ended the record (if one did)."""
    chunks: list[SampledLog] = []
    try:
        for chunk in daq.stream_logging(STEP, chunk_s):
            chunks.append(chunk)
    except RigFault as exc:
        return chunks, exc
    return chunks, None


def _settled(monitor: Monitor, last: str) -> list[tuple[str, int]]:
    """The monitor's transcript once the ``last`` line arrived (the notifier thread lags; on
    a loaded machine by seconds, so the wait ends on the line, with 10 s as the limit)."""
    deadline_s = time.monotonic() + 10.0
    while not (monitor.lines and monitor.lines[-1][0] == last) and time.monotonic() < deadline_s:
        threading.Event().wait(0.02)
    return list(monitor.lines)


def test_timed_start_frame_layout() -> None:
    payload = cf.timed_command_payload(230_001, session=0xBEEF)
    assert payload.hex(" ") == "04 ef be 71 82 03 00 00"  # opcode, u16 session, u32 samples, 0
    assert cf.command_samples(payload) == 230_001 and cf.command_session(payload) == 0xBEEF
    with pytest.raises(ValueError, match="u32"):
        cf.timed_command_payload(1 << 32)
    chunk = cf.status_payload(cf.LoggerState.CHUNK, 8192, session=7)
    assert chunk.hex(" ") == "03 00 07 00 00 20 00 00"
    fault = cf.parse_status(cf.status_payload(cf.LoggerState.FAULT, 5, cf.LoggerError.OVERRUN))
    assert fault.state == cf.LoggerState.FAULT and fault.errors == cf.LoggerError.OVERRUN


def test_chunk_unwraps_its_counters_from_where_it_starts() -> None:
    seq = np.arange(70_000, 70_010) % cf.SEQ_MODULO
    np.testing.assert_array_equal(cf.frame_index(seq, 70_000), np.arange(70_000, 70_010))
    # two frames lost at the chunk's start still show as a gap from its first frame
    np.testing.assert_array_equal(cf.frame_index(seq[2:], 70_000), np.arange(70_002, 70_010))


def test_transcript_of_a_timed_record(timed_pair: Callable) -> None:
    daq, feeder, monitor = timed_pair()
    assert isinstance(daq, StreamingDaq) and supports_streaming(daq)
    chunks, fault = _collect(daq)
    assert fault is None
    marks = [("CHUNK", k * CHUNK_MARK_FRAMES) for k in range(1, TOTAL // CHUNK_MARK_FRAMES + 1)]
    expected: list[tuple[str, int]] = [("PING", 0), ("IDLE", 0),  # CanDaq.start
                                       ("TIMED_START", STEP.samples), ("LOGGING", 0)]
    for (state, sent), before in zip(marks, [0, *[m[1] for m in marks]], strict=False):
        expected += [("samples", sent - before), (state, sent)]
    expected += [("samples", TOTAL - marks[-1][1]), ("END_OF_RECORD", TOTAL)]
    assert _settled(monitor, "END_OF_RECORD") == expected
    assert feeder.asked == [STEP.samples]
    # the chunks are the record, in order, each ≥ chunk_s (6 s = 12 000 frames, so two marked
    # blocks) but the last
    got = concatenate_logs(chunks)
    np.testing.assert_allclose(got["v_sz"], feeder.full["v_sz"], rtol=1.2e-7)  # float32 volts
    np.testing.assert_array_equal(got["trigger"], feeder.full["trigger"])
    assert [len(c) for c in chunks] == [2 * CHUNK_MARK_FRAMES, TOTAL - 2 * CHUNK_MARK_FRAMES]


def test_memory_is_one_chunk_and_one_block_whatever_the_length(timed_pair: Callable) -> None:
    """The plugin never holds the whole record: the frames held at once are bounded by the
    chunk asked for plus one logger block, not by the record's length."""
    long = StreamingFeeder(record(n=3 * TOTAL))
    daq, _, _ = timed_pair(feeder=long)
    chunks, fault = _collect(daq, chunk_s=2.0)  # 4 000 frames: every mark hands a chunk on
    assert fault is None and sum(len(c) for c in chunks) == 3 * TOTAL
    assert 0 < daq.peak_buffered_frames <= 2 * CHUNK_MARK_FRAMES < 3 * TOTAL / 5


def test_lost_frames_end_the_record_after_the_frames_before_them(timed_pair: Callable) -> None:
    # paced as a logger sends (5 kHz: the 5 424 frames after the chunk mark that reveals the
    # loss take ≈ 1.1 s): unpaced, a loaded machine let the simulator send all 30 000 frames
    # before the host's STOP reached it, and the early end this test checks never happened
    daq, feeder, monitor = timed_pair(CanFaultInjection(drop_frames=frozenset({20_000, 20_001})),
                                      frame_rate_hz=5000.0)
    chunks, fault = _collect(daq)
    assert fault is not None and "lost 2 sample frames of the timed record (2 from frame " \
        "20000; 24576 sent so far); the frames before the loss are recorded" in str(fault)
    assert sum(len(c) for c in chunks) == 20_000  # every frame before the loss is handed on
    np.testing.assert_allclose(concatenate_logs(chunks)["v_sz"], feeder.full["v_sz"][:20_000],
                               rtol=1.2e-7)
    lines = _settled(monitor, "END_OF_RECORD")
    assert ("STOP", 0) in lines and lines[-1][0] == "END_OF_RECORD"  # the logger was stopped
    assert lines[-1][1] < TOTAL


def test_a_whole_lost_chunk_is_a_fault(timed_pair: Callable) -> None:
    lost = frozenset(range(CHUNK_MARK_FRAMES, 2 * CHUNK_MARK_FRAMES))
    daq, _, _ = timed_pair(CanFaultInjection(drop_frames=lost), on_frame_loss="record")
    chunks, fault = _collect(daq, chunk_s=1.0)
    assert fault is not None and f"lost {CHUNK_MARK_FRAMES} sample frames" in str(fault)
    assert sum(len(c) for c in chunks) == CHUNK_MARK_FRAMES


def test_a_lost_chunk_mark_is_covered_by_the_next(timed_pair: Callable) -> None:
    daq, _, monitor = timed_pair(CanFaultInjection(drop_marks=frozenset({1})))
    chunks, fault = _collect(daq, chunk_s=1.0)
    assert fault is None and sum(len(c) for c in chunks) == TOTAL
    assert len(chunks[0]) == 2 * CHUNK_MARK_FRAMES  # the second mark accounts for both blocks
    assert ("CHUNK", CHUNK_MARK_FRAMES) not in _settled(monitor, "END_OF_RECORD")


def test_losses_recorded_as_nan_samples(timed_pair: Callable) -> None:
    daq, feeder, _ = timed_pair(CanFaultInjection(drop_frames=frozenset({9000, 9001, 9002})),
                                on_frame_loss="record")
    chunks, fault = _collect(daq)
    assert fault is None
    got = concatenate_logs(chunks)
    assert len(got) == TOTAL and daq.gaps == [cf.Gap(9000, 3)]
    assert np.isnan(got["v_sz"][9000:9003]).all() and np.isnan(got["v_sz"]).sum() == 3
    np.testing.assert_allclose(got.time_s[9000:9003], feeder.full.time_s[9000:9003], atol=1e-9)


def test_logger_overrun_is_a_rig_fault_with_the_data_kept(timed_pair: Callable) -> None:
    daq, _, monitor = timed_pair(CanFaultInjection(overrun_after_frames=12_000))
    chunks, fault = _collect(daq)
    assert fault is not None
    assert "ended the timed record after 12000 sample frames: its buffer overran" in str(fault)
    assert sum(len(c) for c in chunks) == 12_000
    assert _settled(monitor, "FAULT")[-1] == ("FAULT", 12_000)


def test_logger_refusing_the_record_is_a_rig_fault(timed_pair: Callable) -> None:
    daq, _, monitor = timed_pair(feeder=StreamingFeeder(None, refuse=True))
    chunks, fault = _collect(daq)
    assert chunks == [] and fault is not None and "refused the timed record" in str(fault)
    assert _settled(monitor, "FAULT")[-2:] == [("LOGGING", 0), ("FAULT", 0)]


def test_bus_off_mid_record_is_a_rig_fault(timed_pair: Callable) -> None:
    daq, _, _ = timed_pair(CanFaultInjection(bus_off_after_frames=15_000))
    chunks, fault = _collect(daq)
    assert fault is not None and "bus-off" in str(fault)
    # the marked blocks before the bus-off are handed on (the unmarked rest is not accounted)
    assert sum(len(c) for c in chunks) == CHUNK_MARK_FRAMES


def test_leaving_a_record_early_stops_the_logger(timed_pair: Callable) -> None:
    daq, _, monitor = timed_pair()
    stream = daq.stream_logging(STEP, 1.0)
    first = next(stream)
    stream.close()  # the runner aborting between chunks
    lines = _settled(monitor, "END_OF_RECORD")
    assert len(first) == CHUNK_MARK_FRAMES and ("STOP", 0) in lines
    assert lines[-1][0] == "END_OF_RECORD" and lines[-1][1] < TOTAL


LONG_PROCEDURE = """\
procedure: can-long-validate
sensor: {model: sr207, serial: "C-2"}
rig: {turntable: sim, daq: sim, chamber: none}
sampling: {rate_hz: 2000, settle_s: 2}
steps:
  - static: {label: up, inner_deg: 0, outer_deg: 0, duration_s: 3600}
  - static: {label: down, inner_deg: 0, outer_deg: 180, duration_s: 3600}
analysis: [sync, bias, noise, drift]
report: {template: calibration-certificate, sign: false}
"""


def test_validate_accepts_long_static_steps_on_the_can_logger(tmp_path: Path) -> None:
    """Two 1 h static steps (7.2 M samples each, 31× the table's log) on the modbus table and
    the CAN logger: accepted because the logger streams (nothing is connected to validate)."""
    procedure, rig = tmp_path / "p.yaml", tmp_path / "rig.yaml"
    procedure.write_text(LONG_PROCEDURE)
    rig.write_text("turntable: {plugin: modbus, host: 127.0.0.1, port: 1}\n"
                   "daq: {plugin: can, interface: virtual, channel: nobody}\n")
    result = CliRunner().invoke(app, ["validate", str(procedure), "--rig", str(rig)])
    assert result.exit_code == 0, result.output
