"""Recording: bit-exact round trips, crash safety (kill -9), and loud errors on bad files."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mcap.reader import NonSeekingReader, make_reader
from mcap.writer import Writer
from recording_data import SENSOR, run_meta, sine_step, step_logs

from aatest.engine.errors import RecordingError
from aatest.engine.logs import SampledLog
from aatest.recording import BLOCK_SAMPLES, ENCODING, RECORDING_NAME, RunRecorder, read_dataset
from aatest.recording.dataset import Dataset

HERE = Path(__file__).parent


def assert_logs_equal(expected: SampledLog, actual: SampledLog) -> None:
    """Bit-exact equality of times and every channel, dtype included."""
    assert actual.source == expected.source
    assert actual.sample_rate_hz == expected.sample_rate_hz
    np.testing.assert_array_equal(actual.time_s, expected.time_s)
    assert set(actual.channels) == set(expected.channels)
    for name, values in expected.channels.items():
        assert actual[name].dtype == values.dtype, name
        np.testing.assert_array_equal(actual[name], values, err_msg=name)
    assert dict(actual.units) == {k: actual.units[k] for k in expected.channels}


def record_run(run_dir: Path, n_steps: int = 3, samples: int = 8192) -> dict[str, tuple]:
    steps = [sine_step(f"s{i:02d}", samples) for i in range(1, n_steps + 1)]
    recorder = RunRecorder(run_dir)
    recorder.write_run_metadata(run_meta(steps))
    logs = {}
    for seed, step in enumerate(steps):
        logs[step.id] = (step, *step_logs(step, seed))
        recorder.write_step(step, logs[step.id][1], logs[step.id][2])
    return logs


def assert_dataset_matches(dataset: Dataset, logs: dict[str, tuple]) -> None:
    assert [s.step.id for s in dataset.steps] == list(logs)
    for data in dataset.steps:
        step, table, daq = logs[data.step.id]
        assert data.step == step
        assert_logs_equal(table, data.table)
        assert_logs_equal(daq, data.daq)


def test_finalized_recording_round_trips_bit_exact(tmp_path: Path) -> None:
    logs = record_run(tmp_path)
    path = RunRecorder(tmp_path).finalize()
    for source in (tmp_path, path):
        dataset = read_dataset(source)
        assert dataset.procedure == "unit-test"
        assert dataset.sensors == (SENSOR,)
        assert dataset.sample_rate_hz == 2000.0
        assert dataset.metadata["complete"] is True
        assert dataset.metadata["seed"] == 7
        assert_dataset_matches(dataset, logs)


def test_interrupted_run_reads_from_step_files(tmp_path: Path) -> None:
    logs = record_run(tmp_path)
    (tmp_path / "steps" / ".004-s04.mcap.tmp-999").write_bytes(b"\x89MCAP0\r\n partial")
    dataset = read_dataset(tmp_path)
    assert dataset.metadata["complete"] is False
    assert_dataset_matches(dataset, logs)


def test_resumed_run_newer_than_merge_reads_step_files(tmp_path: Path) -> None:
    logs = record_run(tmp_path, n_steps=2)
    recorder = RunRecorder(tmp_path)
    recorder.finalize()
    for path in (tmp_path / "steps").glob("*.mcap"):  # as after a plain `cp -r`
        os.utime(path, ns=(2**62, 2**62))
    assert read_dataset(tmp_path).metadata["complete"] is True
    extra = sine_step("s09")
    logs["s09"] = (extra, *step_logs(extra, 9))
    recorder.write_step(extra, logs["s09"][1], logs["s09"][2])
    assert_dataset_matches(read_dataset(tmp_path), logs)


def test_rewriting_a_step_replaces_it(tmp_path: Path) -> None:
    logs = record_run(tmp_path, n_steps=2)
    recorder = RunRecorder(tmp_path)
    step = logs["s02"][0]
    table, daq = step_logs(step, seed=42)
    recorder.write_step(step, table, daq)
    assert recorder.completed_step_ids() == ["s01", "s02"]
    assert len(list((tmp_path / "steps").glob("*.mcap"))) == 2
    assert_logs_equal(daq, read_dataset(tmp_path).steps[1].daq)


def test_plain_mcap_reader_decodes_blocks_as_documented(tmp_path: Path) -> None:
    """With only ``mcap`` and ``protobuf`` (the schema embedded in the file), the DAQ log of a
    step is rebuilt as the format docstring says: stable topic, blocks in sequence order."""
    logs = record_run(tmp_path, n_steps=2)
    path = RunRecorder(tmp_path).finalize()
    _, _, daq = logs["s02"]
    with open(path, "rb") as stream:
        reader = make_reader(stream)
        assert reader.get_header().profile == "aatest"
        names = [m.name for m in reader.iter_metadata()]
        messages = list(reader.iter_messages(topics=["/daq"]))
    assert names == ["run", "step", "step"]
    schema = messages[0][0]
    assert (schema.encoding, messages[0][1].message_encoding) == (ENCODING, ENCODING) == (
        "protobuf", "protobuf")
    pool = descriptor_pool.DescriptorPool()
    for file in descriptor_pb2.FileDescriptorSet.FromString(schema.data).file:
        pool.Add(file)
    block_type = message_factory.GetMessageClass(pool.FindMessageTypeByName(schema.name))
    blocks = [block_type.FromString(m.data) for _, _, m in messages]
    mine = sorted((b for b in blocks if b.step_id == "s02"), key=lambda b: b.sequence)
    assert len(mine) == -(-len(daq) // BLOCK_SAMPLES) and all(b.source == "daq" for b in mine)
    times = [m.log_time for _, _, m in messages]
    assert times == sorted(times)  # one run time line: step s02 after s01

    def packed(ch: Any) -> np.ndarray:
        """Little-endian integers of ``width`` bytes, stored as byte planes when shuffled."""
        stored = np.frombuffer(ch.packed, dtype=np.uint8)
        planes = stored.reshape(ch.width, -1).T.copy() if ch.shuffled else stored
        return planes.view(f"<i{ch.width}").ravel().astype(np.int64)

    def column(name: str) -> np.ndarray:
        parts = []
        for block in mine:
            ch = block.time if name == "time_s" else next(c for c in block.channels
                                                          if c.name == name)
            if not ch.packed:
                parts.append(np.array(ch.values))
                continue
            codes = np.cumsum(packed(ch)) if ch.delta else packed(ch)
            parts.append(codes * ch.quantum + ch.offset)
        return np.concatenate(parts)

    np.testing.assert_array_equal(column("v_sz"), daq["v_sz"])
    np.testing.assert_array_equal(column("time_s"), daq.time_s)
    np.testing.assert_array_equal(column("sync_pulse"), daq["sync_pulse"])
    assert all(next(c for c in b.channels if c.name == "sync_pulse").packed for b in mine)


@pytest.mark.parametrize("kind", ["step", "merged"])
def test_files_are_valid_mcap_for_seeking_and_streaming_readers(tmp_path: Path, kind: str) -> None:
    """CRCs, indexes and statistics agree whichever way a standard reader walks the file."""
    record_run(tmp_path, n_steps=3, samples=3 * BLOCK_SAMPLES + 17)
    recorder = RunRecorder(tmp_path)
    path = recorder.finalize() if kind == "merged" else recorder.step_files()[1]
    with open(path, "rb") as stream:
        seeking = make_reader(stream, validate_crcs=True)
        summary = seeking.get_summary()
        indexed = list(seeking.iter_messages())  # log-time order through the chunk indexes
    with open(path, "rb") as stream:
        streamed = list(NonSeekingReader(stream, validate_crcs=True).iter_messages())
    stats = summary.statistics
    assert stats.message_count == len(indexed) == len(streamed) > 0
    assert stats.channel_count == len(summary.channels)
    assert stats.chunk_count == len(summary.chunk_indexes)
    assert stats.metadata_count == len(summary.metadata_indexes)
    for channel_id, count in stats.channel_message_counts.items():
        assert count == sum(1 for _, ch, _ in streamed if ch.id == channel_id)
    times = [m.log_time for _, _, m in indexed]
    assert times == sorted(times)
    assert (stats.message_start_time, stats.message_end_time) == (times[0], times[-1])
    if kind == "merged":
        # one block schema for the whole run, and one preview schema per logger
        assert len(summary.schemas) == 3
        assert {ch.topic for ch in summary.channels.values()} == {
            "/table", "/daq", "/preview/table", "/preview/daq"}


def test_prune_deletes_the_merged_step_files_finalize_scanned(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """After its merge the recorder deletes the step files it merged without scanning them
    again; a step file written after the merge (not in the recording) stays, and a recorder
    that did not merge scans the directory first."""
    from aatest.recording import writer

    record_run(tmp_path, n_steps=3, samples=4096)
    recorder = RunRecorder(tmp_path)
    recorder.finalize()
    late = sine_step("s09", 4096)
    recorder.write_step(late, *step_logs(late, 9))
    scans: list[Path] = []
    real_scan = writer.scan_step_file
    monkeypatch.setattr(writer, "scan_step_file", lambda path: scans.append(path) or
                        real_scan(path))
    assert recorder.prune_step_files() == 3
    assert scans == []
    assert [p.name.split(".")[0][-3:] for p in recorder.steps_dir.glob("*.mcap")] == ["s09"]
    assert [s.step.id for s in read_dataset(tmp_path / RECORDING_NAME).steps] == \
        ["s01", "s02", "s03"]
    assert RunRecorder(tmp_path).prune_step_files() == 0 and len(scans) == 1  # s09 scanned


def test_finalize_keeps_plan_order_not_write_order(tmp_path: Path) -> None:
    steps = [sine_step(f"s{i}") for i in (1, 2, 3)]
    recorder = RunRecorder(tmp_path)
    recorder.write_run_metadata(run_meta(steps))
    for step in (steps[2], steps[0], steps[1]):
        recorder.write_step(step, *step_logs(step, 0))
    recorder.finalize()
    assert [s.step.id for s in read_dataset(tmp_path).steps] == ["s1", "s2", "s3"]
    assert sorted(p.name for p in (tmp_path / "steps").glob("*.mcap"))[0] == "001-s1.mcap"


def test_sigkill_mid_step_keeps_completed_steps(tmp_path: Path) -> None:
    """Kill the writer while a step's temporary file is being written; nothing is lost."""
    script = f"""
from recording_data import run_meta, sine_step, step_logs
from aatest.recording import RunRecorder
steps = [sine_step(f"s{{i:02d}}", 2**15) for i in range(1, 200)]
rec = RunRecorder({str(tmp_path)!r})
rec.write_run_metadata(run_meta(steps))
for i, step in enumerate(steps):
    rec.write_step(step, *step_logs(step, i))
"""
    # the child imports recording_data from this directory, as pytest does for the tests
    path = os.pathsep.join(filter(None, [str(HERE), os.environ.get("PYTHONPATH")]))
    env = {**os.environ, "PYTHONPATH": path}
    proc = subprocess.Popen([sys.executable, "-c", script], env=env)
    steps_dir = tmp_path / "steps"
    deadline = time.monotonic() + 60
    try:
        while time.monotonic() < deadline:
            done = list(steps_dir.glob("0*.mcap")) if steps_dir.exists() else []
            temps = list(steps_dir.glob(".*.tmp-*")) if steps_dir.exists() else []
            if len(done) >= 2 and temps and temps[0].stat().st_size > 0:
                break
            assert proc.poll() is None, "writer exited early"
            time.sleep(0.002)
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.wait(timeout=30)
    recorder = RunRecorder(tmp_path)
    completed = recorder.completed_step_ids()
    assert len(completed) >= 2
    assert not list(steps_dir.glob(".*.tmp-*")), "partial files must be removed"
    for i, step_id in enumerate(completed):
        step = sine_step(step_id, 2**15)
        table, daq = step_logs(step, i)
        data = read_dataset(tmp_path).steps[i]
        assert_logs_equal(table, data.table)
        assert_logs_equal(daq, data.daq)
    path = recorder.finalize()
    with open(path, "rb") as stream:
        reader = make_reader(stream)
        n_messages = sum(1 for _ in reader.iter_messages())
        assert reader.get_summary().statistics.message_count == n_messages > 0
    assert len(read_dataset(path).steps) == len(completed)


@pytest.mark.parametrize("cut", [0.3, 0.7, 0.99], ids=["early", "middle", "late"])
def test_truncated_recording_is_a_recording_error(tmp_path: Path, cut: float) -> None:
    record_run(tmp_path, n_steps=1)
    path = RunRecorder(tmp_path).finalize()
    data = path.read_bytes()
    bad = tmp_path / "cut.mcap"
    bad.write_bytes(data[: int(len(data) * cut)])
    with pytest.raises(RecordingError, match=r"cut\.mcap"):
        read_dataset(bad)


def test_flipped_bytes_inside_chunks_are_a_recording_error(tmp_path: Path) -> None:
    record_run(tmp_path, n_steps=1)
    path = RunRecorder(tmp_path).finalize()
    data = bytearray(path.read_bytes())
    rng = np.random.default_rng(3)
    for pos in rng.integers(200, len(data) // 2, 64):
        data[pos] ^= 0xFF
    bad = tmp_path / "flipped.mcap"
    bad.write_bytes(bytes(data))
    with pytest.raises(RecordingError, match=r"flipped\.mcap"):
        for step in read_dataset(bad).steps:  # chunks are checked when their step is read
            assert step.table is not None and step.daq is not None


def test_foreign_mcap_and_garbage_are_rejected(tmp_path: Path) -> None:
    foreign = tmp_path / "foreign.mcap"
    with open(foreign, "wb") as stream:
        writer = Writer(stream)
        writer.start(profile="ros2", library="test")
        writer.finish()
    with pytest.raises(RecordingError, match="not an aatest recording"):
        read_dataset(foreign)
    garbage = tmp_path / "garbage.mcap"
    garbage.write_bytes(b"hello, not mcap" * 10)
    with pytest.raises(RecordingError, match=r"garbage\.mcap"):
        read_dataset(garbage)
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(RecordingError, match="not a run or import directory"):
        read_dataset(empty)
    with pytest.raises(RecordingError, match="no such file"):
        read_dataset(tmp_path / "missing.mcap")


def test_step_without_run_metadata_still_recorded(tmp_path: Path) -> None:
    """A recorder used without write_run_metadata still produces readable, defaulted data."""
    step = sine_step("only")
    table, daq = step_logs(step, 1, latch=False)
    RunRecorder(tmp_path).write_step(step, table, daq)
    dataset = read_dataset(RunRecorder(tmp_path).finalize())
    assert dataset.procedure == "unknown"
    assert [s.channel for s in dataset.sensors] == ["v_sz"]
    assert "fp_latch_s" not in dataset.steps[0].table.channels


@pytest.fixture(scope="module")
def small_recording(tmp_path_factory: pytest.TempPathFactory) -> tuple[bytes, Dataset]:
    run_dir = tmp_path_factory.mktemp("small")
    record_run(run_dir, n_steps=2, samples=5000)
    path = RunRecorder(run_dir).finalize()
    return path.read_bytes(), read_dataset(path)


@settings(max_examples=150, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(cut=st.integers(min_value=0), flips=st.lists(
    st.tuples(st.integers(min_value=0), st.integers(min_value=1, max_value=255)), max_size=4))
def test_damaged_recording_is_an_error_or_unchanged(
    tmp_path_factory: pytest.TempPathFactory, small_recording: tuple[bytes, Dataset],
    cut: int, flips: list[tuple[int, int]],
) -> None:
    """Never another exception, and never silently different samples (chunk CRCs).

    Steps are decoded when read, so damage inside a chunk may surface then: still a
    RecordingError naming the file.
    """
    data, reference = small_recording
    damaged = bytearray(data[: len(data) - cut % 64 if cut % 3 == 0 else len(data)])
    for position, mask in flips:
        damaged[position % len(damaged)] ^= mask
    path = tmp_path_factory.mktemp("damaged") / "recording.mcap"
    path.write_bytes(bytes(damaged))
    try:
        dataset = read_dataset(path)
        logs = [(mine.step, mine.table, mine.daq) for mine in dataset.steps]
    except RecordingError as exc:
        assert "recording.mcap" in str(exc)
        return
    for (step, table, daq), ref in zip(logs, reference.steps, strict=True):
        assert step == ref.step
        assert_logs_equal(ref.table, table)
        assert_logs_equal(ref.daq, daq)


def test_a_step_record_with_a_damaged_name_is_an_error_not_a_lost_step(
    tmp_path: Path, small_recording: tuple[bytes, Dataset],
) -> None:
    """A flipped bit in a step record's name ("step" → "rtep") made the reader pass over the
    record, and the recording read without that step (found by the test above). The
    summary's index names each record: a record named otherwise is damage."""
    data, _ = small_recording
    path = tmp_path / "recording.mcap"
    path.write_bytes(data)
    with path.open("rb") as stream:
        first_step = next(ix for ix in make_reader(stream).get_summary().metadata_indexes
                          if ix.name == "step")
    damaged = bytearray(data)
    name_at = first_step.offset + 1 + 8 + 4  # opcode, record length, the name's length
    assert damaged[name_at:name_at + 4] == b"step"
    damaged[name_at] ^= 1
    path.write_bytes(bytes(damaged))
    with pytest.raises(RecordingError, match=r"recording\.mcap: the metadata record at byte "
                       rf"{first_step.offset} is named 'rtep', its index 'step' \(damaged\)"):
        read_dataset(path)


def test_golden_v1_recording_still_reads_bit_exact() -> None:
    """A recording written by format v1 (``aatest.block/v1``, per-step topics) keeps reading.

    ``data/golden_v1/recording.mcap`` was written by the v1 writer from ``step_logs`` (2 steps
    of 2048 samples, seeds 0 and 1); the reader dispatches on the schema encoding.
    """
    dataset = read_dataset(HERE / "data" / "golden_v1" / "recording.mcap")
    steps = [sine_step(f"s{i:02d}", 2048) for i in (1, 2)]
    expected = {step.id: (step, *step_logs(step, seed)) for seed, step in enumerate(steps)}
    assert_dataset_matches(dataset, expected)


#: a recording written by format v2 (codes as varints): the streaming tests' small stepped sine
GOLDEN_V2 = HERE / "data" / "streaming" / "recording.mcap"


def test_golden_v2_recording_still_reads_and_rewrites_as_v3_bit_exact(tmp_path: Path) -> None:
    """A v2 recording (``codes`` as varints) reads; written again by this version (v3,
    ``packed``), every log reads back bit for bit, in a smaller file."""
    from aatest.recording import FORMAT
    from aatest.recording.format import FORMAT_V2

    old = read_dataset(GOLDEN_V2)
    assert old.metadata["format"] == FORMAT_V2 and FORMAT != FORMAT_V2
    recorder = RunRecorder(tmp_path)
    recorder.write_run_metadata({k: v for k, v in old.metadata.items() if k != "format"})
    steps = list(old.steps)
    for step in steps:
        recorder.write_step(step.step, step.table, step.daq)
    path = recorder.finalize()
    new = read_dataset(path)
    assert new.metadata["format"] == FORMAT
    for before, after in zip(steps, new.steps, strict=True):
        assert after.step == before.step
        assert_logs_equal(before.table, after.table)
        assert_logs_equal(before.daq, after.daq)
    assert path.stat().st_size < GOLDEN_V2.stat().st_size


def _adc(volts: np.ndarray, lsb_v: float, lo_v: float) -> np.ndarray:
    """A 16-bit ±10 V ADC reading: code·LSB + low end, as the twin's DAQ computes it."""
    return np.round((volts - lo_v) / lsb_v) * lsb_v + lo_v


@pytest.mark.parametrize("on_grid", [True, False], ids=["adc-codes", "off-grid-float"])
def test_quantised_channels_round_trip_bit_exact_as_codes_or_floats(
    tmp_path: Path, on_grid: bool
) -> None:
    """decode(encode(x)) == x bit for bit: as codes on the declared grid, as float64 off it."""
    from aatest.recording.codec import encode_blocks
    from aatest.recording.proto import block_class

    step = sine_step("s01", 3 * BLOCK_SAMPLES + 5)
    table, daq = step_logs(step, seed=3)
    lsb_v, lo_v = 20.0 / 2**16, -10.0
    volts = _adc(daq["v_sz"], lsb_v, lo_v) if on_grid else daq["v_sz"]
    daq = SampledLog(daq.source, daq.sample_rate_hz, daq.time_s,
                     {**daq.channels, "v_sz": volts}, daq.units, {"v_sz": (lsb_v, lo_v)})
    recorder = RunRecorder(tmp_path)
    recorder.write_step(step, table, daq)
    got = read_dataset(recorder.finalize()).steps[0].daq
    assert got["v_sz"].view(np.uint64).tolist() == volts.view(np.uint64).tolist()
    assert dict(got.quantisation) == {"v_sz": (lsb_v, lo_v)}
    header = {"step_id": "s01", "source": "daq"}
    blocks = [block_class().FromString(b) for b in encode_blocks(daq, header, BLOCK_SAMPLES,
                                                                 [0, 1, 2, 3])]
    coded = [len(next(c for c in b.channels if c.name == "v_sz").packed) > 0 for b in blocks]
    assert coded == [on_grid] * 4


def test_one_sample_off_the_grid_keeps_only_its_block_as_floats(tmp_path: Path) -> None:
    """Never lossy silently: a single value off the ADC grid makes its block float64."""
    step = sine_step("s01", 2 * BLOCK_SAMPLES)
    table, daq = step_logs(step, seed=4)
    lsb_v, lo_v = 20.0 / 2**16, -10.0
    volts = _adc(daq["v_sz"], lsb_v, lo_v)
    volts[BLOCK_SAMPLES + 7] += lsb_v / 3
    daq = SampledLog(daq.source, daq.sample_rate_hz, daq.time_s,
                     {**daq.channels, "v_sz": volts}, daq.units, {"v_sz": (lsb_v, lo_v)})
    recorder = RunRecorder(tmp_path)
    recorder.write_step(step, table, daq)
    got = read_dataset(recorder.finalize()).steps[0].daq
    np.testing.assert_array_equal(got["v_sz"], volts)
    assert got["v_sz"].view(np.uint64).tolist() == volts.view(np.uint64).tolist()


def test_encoder_counts_with_negative_zero_stay_codes() -> None:
    """A rounded encoder reading just below 0 is −0.0: equal to 0.0, so the block stays codes."""
    from aatest.recording.codec import channel_values, encode_blocks, samples_in
    from aatest.recording.proto import block_class

    q_deg = 0.01 / 3600.0
    angle = np.round(np.random.default_rng(5).normal(0, 3 * q_deg, 1000) / q_deg) * q_deg
    assert np.any(np.signbit(angle) & (angle == 0))
    log = SampledLog("table", 2000.0, np.arange(1000) / 2000.0, {"inner_position_deg": angle},
                     {"inner_position_deg": "deg"}, {"inner_position_deg": (q_deg, 0.0)})
    block = block_class().FromString(next(encode_blocks(log, {}, BLOCK_SAMPLES, [0])))
    values, quantum = channel_values(block.channels[0])
    assert quantum == (q_deg, 0.0) and samples_in(block.channels[0]) == 1000
    assert block.channels[0].packed and not block.channels[0].values
    np.testing.assert_array_equal(values, angle)
    nonzero = angle != 0
    assert values[nonzero].view(np.uint64).tolist() == angle[nonzero].view(np.uint64).tolist()


QUICK = HERE.parents[1] / "tests" / "data" / "procedures" / "quick-sine-3-steps.yaml"
#: runs the CLI with the recorder's file writes failing with ENOSPC once the file whose name
#: contains FAIL_IN has received FAIL_AFTER bytes (a disk that fills up mid-write)
_FULL_DISK_CLI = """
import builtins, errno, os, sys
from aatest.recording import writer

class _FullDisk:
    def __init__(self, stream):
        self._stream, self._left = stream, int(os.environ["FAIL_AFTER"])
    def write(self, data):
        if len(data) > self._left:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        self._left -= len(data)
        return self._stream.write(data)
    def __getattr__(self, name):
        return getattr(self._stream, name)
    def __enter__(self):
        return self
    def __exit__(self, *exc):
        return self._stream.__exit__(*exc)

def _open(path, mode="r", *args, **kwargs):
    stream = builtins.open(path, mode, *args, **kwargs)
    fail_in = os.environ.get("FAIL_IN")
    return _FullDisk(stream) if fail_in and fail_in in str(path) and "w" in mode else stream

writer.open = _open
from aatest.cli import main
sys.argv = ["aatest", *sys.argv[1:]]
main()
"""


def _cli(run_dir: Path, *extra: str, fail_in: str = "", fail_after: int = 0) -> tuple[int, str]:
    env = {**os.environ, "FAIL_IN": fail_in, "FAIL_AFTER": str(fail_after)}
    done = subprocess.run(
        [sys.executable, "-c", _FULL_DISK_CLI, "run", str(QUICK), "--out", str(run_dir),
         "--no-progress", *extra], capture_output=True, text=True, timeout=300, env=env,
        stdin=subprocess.DEVNULL, check=False)
    return done.returncode, done.stderr


def _step_files(run_dir: Path) -> list[str]:
    """Plan position and suffix of every file in ``steps/``: ``001.mcap``, ``002.mcap.corrupt``."""
    return sorted(p.name[:3] + (".mcap.corrupt" if p.name.endswith(".corrupt") else ".mcap")
                  for p in (run_dir / "steps").iterdir() if p.name != "run.json")


def _recorded_ids(path: Path) -> list[str]:
    return [s.step.id for s in read_dataset(path).steps]


@pytest.mark.parametrize("fail_in", ["002-", "recording.mcap"], ids=["writing-step", "merging"])
def test_full_disk_is_a_fault_that_keeps_steps_and_resumes(tmp_path: Path, fail_in: str) -> None:
    """ENOSPC while a step file or the merged recording is written: exit 3, one reason line,
    no half-written file, the completed steps intact; ``--resume`` then completes the run."""
    run_dir = tmp_path / "run"
    code, stderr = _cli(run_dir, fail_in=fail_in, fail_after=50_000)
    assert code == 3, stderr
    assert "No space left on device" in stderr and "--resume" in stderr
    assert "Traceback" not in stderr
    kept = _step_files(run_dir)
    assert kept == (["001.mcap"] if fail_in == "002-" else ["001.mcap", "002.mcap", "003.mcap"])
    assert not (run_dir / "recording.mcap").exists()
    assert len(_recorded_ids(run_dir)) == len(kept)  # the kept steps read
    code, stderr = _cli(run_dir, "--resume")
    assert code == 0, stderr
    ids = _recorded_ids(run_dir / "recording.mcap")
    assert len(ids) == len(set(ids)) == 3


def test_corrupt_step_file_on_resume_is_named_and_the_others_kept(tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    code, _ = _cli(run_dir, fail_in="003-", fail_after=10_000)
    assert code == 3
    damaged = next((run_dir / "steps").glob("001-*.mcap"))
    damaged.write_bytes(damaged.read_bytes()[:5000])
    code, stderr = _cli(run_dir, "--resume")
    assert code == 2, stderr
    assert str(damaged) in stderr and "corrupt step file" in stderr and "Traceback" not in stderr
    assert _step_files(run_dir) == ["001.mcap.corrupt", "002.mcap"]
    code, stderr = _cli(run_dir, "--resume")
    assert code == 0, stderr
    ids = _recorded_ids(run_dir / "recording.mcap")
    assert len(ids) == len(set(ids)) == 3


MCAP_TS = HERE.parent / "mcap_ts"


def _summary(recording: Path) -> dict[str, object]:
    """What the TypeScript check must find: messages per topic, samples, first/last values."""
    with open(recording, "rb") as stream:
        counts = make_reader(stream).get_summary().statistics.channel_message_counts
    steps: dict[str, object] = {}
    for data in read_dataset(recording).steps:
        for log in (data.table, data.daq):
            arrays = {"time_s": log.time_s, **log.channels}
            steps[f"{data.step.id}/{log.source}"] = {
                "samples": len(log),
                "first": {k: v[0].item() for k, v in arrays.items()},
                "last": {k: v[-1].item() for k, v in arrays.items()},
            }
    return {"messages": {"/table": counts[1], "/daq": counts[2]}, "steps": steps}


def test_official_typescript_reader_decodes_a_recording(tmp_path: Path) -> None:
    """``@mcap/core`` reads every record (CRCs validated), protobufjs decodes the embedded
    schema, and the decoded counts and values equal what aatest reads."""
    node = shutil.which("node")
    if node is None or not (MCAP_TS / "node_modules" / "@mcap" / "core").is_dir():
        pytest.skip("needs node and `npm ci --prefix tests/mcap_ts` (done by .ci/run)")
    record_run(tmp_path, n_steps=2, samples=2 * BLOCK_SAMPLES + 9)
    recording = RunRecorder(tmp_path).finalize()
    summary = tmp_path / "summary.json"
    summary.write_text(json.dumps(_summary(recording)))
    done = subprocess.run([node, str(MCAP_TS / "read_recording.mjs"), str(recording),
                           str(summary)], capture_output=True, text=True, timeout=120,
                          check=False)
    assert done.returncode == 0, done.stderr
    assert "CRCs valid" in done.stdout


def test_official_typescript_reader_decodes_a_v2_recording(tmp_path: Path) -> None:
    """The same check on a recording of format v2 (varint ``codes``): viewers keep decoding
    older recordings with the schema embedded in them."""
    node = shutil.which("node")
    if node is None or not (MCAP_TS / "node_modules" / "@mcap" / "core").is_dir():
        pytest.skip("needs node and `npm ci --prefix tests/mcap_ts` (done by .ci/run)")
    summary = tmp_path / "summary.json"
    summary.write_text(json.dumps(_summary(GOLDEN_V2)))
    done = subprocess.run([node, str(MCAP_TS / "read_recording.mjs"), str(GOLDEN_V2),
                           str(summary)], capture_output=True, text=True, timeout=120,
                          check=False)
    assert done.returncode == 0, done.stderr
    assert "CRCs valid" in done.stdout


def test_typescript_check_fails_on_a_wrong_summary(tmp_path: Path) -> None:
    """The check can fail: one changed value in the summary is reported."""
    node = shutil.which("node")
    if node is None or not (MCAP_TS / "node_modules" / "@mcap" / "core").is_dir():
        pytest.skip("needs node and `npm ci --prefix tests/mcap_ts` (done by .ci/run)")
    record_run(tmp_path, n_steps=1)
    recording = RunRecorder(tmp_path).finalize()
    summary = _summary(recording)
    summary["steps"]["s01/daq"]["last"]["v_sz"] += 1e-9  # type: ignore[index]
    path = tmp_path / "summary.json"
    path.write_text(json.dumps(summary))
    done = subprocess.run([node, str(MCAP_TS / "read_recording.mjs"), str(recording), str(path)],
                          capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 1 and "v_sz" in done.stderr
