"""A step's logs handed to the early child in shared memory: the arrays a decode of the step
file gives (bit for bit, ``-0.0`` in coded blocks included), the same ``Made`` as the child
decoding, the run-time check's relation the one the child would fit, the fallback to the
file, and no memory file left behind."""

from __future__ import annotations

import gc
import os
import pickle
import signal
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from recording_data import run_meta, sine_step, step_logs

from aatest.clocksync.freeze_pulse import clock_relation
from aatest.early import analysis as early_analysis
from aatest.early import handover
from aatest.early.analysis import EarlyAnalysis, _Notifying
from aatest.early.child import _Child, _received
from aatest.early.made import StepSent
from aatest.engine.logs import SampledLog
from aatest.engine.registry import pinned
from aatest.recording import RunRecorder, read_dataset
from aatest.recording import format as fmt
from aatest.recording.dataset import StepData
from aatest.recording.step_chunks import step_digests

ANALYSIS = ["sync", "frf"]
SAMPLES = 3 * fmt.BLOCK_SAMPLES + 100  # a short last block


def _logs(seed: int) -> tuple[Any, SampledLog, SampledLog]:
    """A sine step whose resting axis' rate holds ``-0.0`` in a coded block (all whole
    numbers: stored as codes) and in a block stored as values (one value off the grid)."""
    step = sine_step(f"s{seed:02d}", samples=SAMPLES)
    table, daq = step_logs(step, seed)
    rate = np.zeros(len(table))
    rate[5:50] = -0.0  # block 0: coded, comes back +0.0
    rate[fmt.BLOCK_SAMPLES + 3: fmt.BLOCK_SAMPLES + 9] = -0.0  # block 1: raw, stays -0.0
    rate[fmt.BLOCK_SAMPLES + 20] = 0.5
    rate[2 * fmt.BLOCK_SAMPLES + 7] = np.nan  # block 2: raw (NaN never codes)
    channels = {**table.channels, "outer_rate_dps": rate}
    return step, SampledLog(table.source, table.sample_rate_hz, table.time_s, channels,
                            table.units, table.quantisation), daq


def _recorded(run_dir: Path, seeds: range = range(1, 3)
              ) -> tuple[RunRecorder, list[tuple[Any, SampledLog, SampledLog]], dict[str, Any]]:
    made = [_logs(seed) for seed in seeds]
    recorder = RunRecorder(run_dir)
    recorder.write_run_metadata({**run_meta([m[0] for m in made]), "analysis": ANALYSIS})
    coded: dict[str, Any] = {}
    for step, table, daq in made:
        coded[step.id] = {}
        recorder.write_step(step, table, daq, coded=coded[step.id])
    return recorder, made, coded


def _mapped(recorder: RunRecorder, step: Any, table: SampledLog, daq: SampledLog,
            coded: Any, wanted: Any = None) -> handover.Mapped:
    path = next(p for p in recorder.step_files() if step.id in p.name)
    segment = handover.Segment()
    try:
        handover.fill(segment, (table, table), coded | {"table": coded["table"]},
                      fmt.BLOCK_SAMPLES)  # reused: a larger fill first
        layouts, size, exact = handover.fill(segment, (table, daq), coded, fmt.BLOCK_SAMPLES,
                                             wanted)
        digest = step_digests(path, only={step.id})[step.id]
        return handover.Mapped(segment.fd, handover.Handed(digest, size, fmt.BLOCK_SAMPLES,
                                                           layouts, exact))
    finally:
        segment.close()


def _same(a: SampledLog, b: SampledLog) -> None:
    """Equal bit for bit: arrays (dtype, bytes, order), rate, units, quantisation."""
    assert (a.source, a.sample_rate_hz, dict(a.units), dict(a.quantisation)) == (
        b.source, b.sample_rate_hz, dict(b.units), dict(b.quantisation))
    assert list(a.channels) == list(b.channels)
    for x, y in [(a.time_s, b.time_s), *zip(a.channels.values(), b.channels.values(),
                                             strict=True)]:
        assert x.dtype == y.dtype and x.tobytes() == y.tobytes()
        assert not x.flags.writeable


def test_handed_logs_are_the_decoded_ones_bit_for_bit(tmp_path: Path) -> None:
    recorder, made, coded = _recorded(tmp_path, range(1, 2))
    step, table, daq = made[0]
    assert coded[step.id]["table"]["outer_rate_dps"][:3] == [True, False, False]
    mapped = _mapped(recorder, step, table, daq, coded[step.id])
    decoded = read_dataset(recorder.step_files()[0]).steps
    for source in ("table", "daq"):
        _same(mapped.log(source), decoded.log(0, source))
        for channels in (["outer_rate_dps", "sync_pulse"], ["v_sz", "nope"], []):
            _same(mapped.log(source, channels), decoded.log(0, source, channels))
        pieces = list(mapped.pieces(source, ["sync_pulse"]))
        assert len(pieces) == len(list(decoded.pieces(0, source, ["sync_pulse"])))
        for ours, theirs in zip(pieces, decoded.pieces(0, source, ["sync_pulse"]), strict=True):
            _same(ours, theirs)
    rate = mapped.log("table")["outer_rate_dps"]
    assert not np.signbit(rate[5:50]).any()  # the coded block's -0.0 came back +0.0
    assert np.signbit(rate[fmt.BLOCK_SAMPLES + 3: fmt.BLOCK_SAMPLES + 9]).all()  # kept
    assert mapped.handed.relation_inputs_exact  # no -0.0 among the sync channels
    mapped.close()
    some = _mapped(recorder, step, table, daq, coded[step.id], {"daq": {"v_sz"}})
    assert list(some.logs["table"].channels) == ["sync_pulse", "fp_latch_s"]  # the relation's
    assert some.holds("daq", ["v_sz", "trigger"]) and not some.holds("daq", None)
    assert not some.holds("table", ["outer_rate_dps"])
    _same(some.log("daq", ["v_sz"]), decoded.log(0, "daq", ["v_sz"]))
    some.close()


def test_a_minus_zero_in_a_relation_input_withholds_the_relation(tmp_path: Path) -> None:
    step, table, daq = _logs(1)
    time_s = np.arange(len(table)) * 2.0**-10  # on a grid: coded
    time_s[0] = -0.0  # the copy then differs from what a relation was fitted on
    table = SampledLog(table.source, table.sample_rate_hz, time_s, table.channels, table.units,
                       {"time_s": (2.0**-10, 0.0)})
    recorder = RunRecorder(tmp_path)
    recorder.write_run_metadata({**run_meta([step]), "analysis": ANALYSIS})
    coded: dict[str, Any] = {}
    recorder.write_step(step, table, daq, coded=coded)
    assert coded["table"]["time_s"][0]
    mapped = _mapped(recorder, step, table, daq, coded)
    assert not mapped.handed.relation_inputs_exact
    _same(mapped.log("table"), read_dataset(recorder.step_files()[0]).steps.log(0, "table"))
    mapped.close()


@pytest.mark.parametrize("wanted", [None, {"table": {"inner_accel_dps2"}}])
def test_made_via_handover_is_made_via_decode_and_takes_the_checks_relation(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, wanted: Any) -> None:
    """Every channel handed, or only some (the rest then decoded from the file)."""
    with pinned():
        recorder, made, coded = _recorded(tmp_path)
        fits: list[str] = []
        import aatest.plugins.analysis.sync_watches as watches

        real = watches.fit_and_synchronise

        def counted(data: StepData) -> Any:
            fits.append(data.step.id)
            return real(data)

        monkeypatch.setattr(watches, "fit_and_synchronise", counted)
        decoding, handed = _Child(), _Child()
        for (step, table, daq), path in zip(made, recorder.step_files(), strict=True):
            relation = clock_relation(StepData(step, table, daq))  # the run-time check's
            by_decode = decoding.analyse(step.id, path)
            assert fits == [step.id]  # fitted by the decoding child
            mapped = _mapped(recorder, step, table, daq, coded[step.id], wanted)
            by_hand = handed.analyse(step.id, path, mapped, relation)
            assert "sync_pulse" in mapped.read["daq"]  # what it read, handed or not
            mapped.close()
            assert fits == [step.id]  # not fitted again: the check's relation was taken
            fits.clear()
            assert by_decode is not None and by_hand is not None
            assert by_decode.results["sync"][0] == relation  # what the child would fit
            assert pickle.dumps(by_hand) == pickle.dumps(by_decode)  # bit for bit


def test_without_a_segment_the_child_decodes_the_file(tmp_path: Path) -> None:
    with pinned():
        recorder, made, _ = _recorded(tmp_path, range(1, 2))
        step = made[0][0]
        path = recorder.step_files()[0]
        handed = handover.Handed("0" * 64, 64, fmt.BLOCK_SAMPLES, (), True)
        assert _received(None, StepSent(step.id, str(path), handed)) is None
        made_now = _Child().analyse(step.id, path, None, None)
        assert made_now is not None
        assert made_now.digest == step_digests(path)[step.id]


def _memfds(pid: int) -> int:
    """Memory files of the handover open or mapped in process ``pid``."""
    fds = sum("aatest-early-step" in os.readlink(f"/proc/{pid}/fd/{fd}")
              for fd in os.listdir(f"/proc/{pid}/fd") if os.path.exists(f"/proc/{pid}/fd/{fd}"))
    maps = Path(f"/proc/{pid}/maps").read_text().count("aatest-early-step")
    return fds + maps


@pytest.mark.skipif(not hasattr(os, "memfd_create"), reason="no memory files")
@pytest.mark.parametrize("killed", [False, True])
def test_segments_are_gone_after_the_run_and_a_killed_child(tmp_path: Path,
                                                            killed: bool) -> None:
    _, made, _ = _recorded(tmp_path / "src", range(1, 5))
    out = RunRecorder(tmp_path / "run")
    out.write_run_metadata({**run_meta([m[0] for m in made]), "analysis": ANALYSIS})
    gc.collect()
    before = _memfds(os.getpid())  # views of an earlier test's mapped segments, if any
    early = EarlyAnalysis()
    try:
        notifying = _Notifying(out, early, [m[0] for m in made])
        if killed:
            os.kill(early.pid, signal.SIGSTOP)  # it queues, then dies holding them
        for k, (step, table, daq) in enumerate(made):
            if k == early_analysis.MAX_HANDED and not killed:  # the child takes them first
                deadline = time.monotonic() + 120.0
                while early._handed and time.monotonic() < deadline:
                    time.sleep(0.05)
            notifying.write_step(step, table, daq)
            # each: its descriptor, the one its mmap keeps, the mapping
            assert _memfds(os.getpid()) - before <= 3 * early_analysis.MAX_HANDED
        if killed:
            assert len(early._handed) == early_analysis.MAX_HANDED  # the rest decoded
            os.kill(early.pid, signal.SIGKILL)
            results = early.results()
        else:
            results = early.results(drain=True)
            assert early.handed_steps > early_analysis.MAX_HANDED  # segments were reused
            assert set(results.made) == {m[0].id for m in made}
            assert all(results.made[m[0].id].digest == step_digests(p)[m[0].id]
                       for m, p in zip(made, out.step_files(), strict=True))
    finally:
        early.close()
    assert _memfds(os.getpid()) == before
    assert early._segments is None or early._segments.fileno() == -1
