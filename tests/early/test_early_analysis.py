"""The sync pass's per-step work made during the record phase: taken only for the same bytes,
equal results, and the child never outlives the run."""

from __future__ import annotations

import json
import logging
import os
import shutil
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader

from aatest.early import analysis as early_analysis
from aatest.early import process
from aatest.early.analysis import EarlyAnalysis, EarlyResults
from aatest.engine.errors import RecordingError, RigFault
from aatest.engine.logs import SampledLog
from aatest.engine.run import session
from aatest.engine.run.events import NullObserver, RunEvents
from aatest.engine.steps import PlannedStep
from aatest.recording import read_dataset
from aatest.recording.step_chunks import step_digests

DATA = Path(__file__).parents[1] / "station" / "data"
SINES = DATA / "quick-sine-3-steps.yaml"
LONG_STATIC = DATA / "quick-long-static.yaml"
#: what results.json says about the analysis (the rest is run metadata and times)
ANALYSED = ("analysis", "analysis_errors", "analysis_skipped", "figures", "logged_temperature",
            "overall", "steps", "verdicts")


def _taken(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records if "sync pass:" in r.getMessage()]


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Path, EarlyResults]]:
    """A 3-step stepped-sine run whose child analysed every step (it is drained at the end of
    the record phase instead of stopped, so none is left to the pass by timing)."""
    made: list[EarlyResults] = []
    real = EarlyAnalysis.results

    def drained(self: EarlyAnalysis, drain: bool = False) -> EarlyResults:
        made.append(real(self, drain=True))
        return made[-1]

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(EarlyAnalysis, "results", drained)
        run = tmp_path_factory.mktemp("early") / "run"
        session.run(SINES, None, run, False, 1, None, show_progress=False)
    yield run, made[0]


def _analysed(run: Path) -> dict[str, Any]:
    results = json.loads((run / "results.json").read_text())
    return {key: results.get(key) for key in ANALYSED}


@pytest.mark.slow  # a run and its child's imports: ≈ 6 s idle, more under load
def test_the_pass_takes_the_steps_analysed_while_recording(
        recorded: tuple[Path, EarlyResults], tmp_path: Path,
        caplog: pytest.LogCaptureFixture) -> None:
    run, early = recorded
    assert early.offered == 3 and len(early.made) == 3
    assert early.complete  # drained: its last word was that it had made all
    caplog.set_level(logging.DEBUG, "aatest.analysis")
    session.analyse_and_report(run, tmp_path / "again")  # `aatest analyze`: nothing taken
    assert _taken(caplog) == ["sync pass: 0 of 3 steps taken as analysed while the run recorded"]
    assert _analysed(tmp_path / "again") == _analysed(run)  # every value, figure and verdict
    caplog.clear()
    session.analyse_and_report(run, tmp_path / "taken", early=early)
    assert _taken(caplog) == ["sync pass: 3 of 3 steps taken as analysed while the run recorded"]
    assert _analysed(tmp_path / "taken") == _analysed(run)


@pytest.mark.slow  # a run and its child's imports: ≈ 6 s idle, more under load
def test_a_step_made_of_other_bytes_is_computed_again(
        recorded: tuple[Path, EarlyResults], tmp_path: Path,
        caplog: pytest.LogCaptureFixture) -> None:
    run, early = recorded
    ids = list(early.made)
    swapped = EarlyResults({**early.made, ids[1]: early.made[ids[0]]})  # step 1's bytes as 2's
    caplog.set_level(logging.DEBUG, "aatest.analysis")
    session.analyse_and_report(run, tmp_path / "out", early=swapped)
    assert swapped.offered == 2
    assert _taken(caplog) == ["sync pass: 2 of 3 steps taken as analysed while the run recorded"]
    assert _analysed(tmp_path / "out") == _analysed(run)


@pytest.mark.slow  # a run and its child's imports: ≈ 6 s idle, more under load
def test_a_damaged_chunk_is_never_taken_and_fails_as_without(
        recorded: tuple[Path, EarlyResults], tmp_path: Path) -> None:
    run, early = recorded
    copy = tmp_path / "run"
    shutil.copytree(run, copy)
    recording = copy / "recording.mcap"
    digests = step_digests(recording)
    assert {k: v.digest for k, v in early.made.items()} == digests  # the merge copied verbatim
    _flip_a_byte_of_the_last_chunk(recording)
    assert step_digests(recording) != digests
    assert early.offer(read_dataset(copy)) == 2
    with pytest.raises(RecordingError, match=r"CRC|corrupt"):  # met in the pass, as without
        session.analyse_and_report(copy, tmp_path / "out", early=early)


def _flip_a_byte_of_the_last_chunk(recording: Path) -> None:
    with open(recording, "rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None
    last = max((ix for ix in summary.chunk_indexes if 2 in ix.message_index_offsets),
               key=lambda ix: ix.chunk_start_offset)  # the last step's DAQ blocks
    offset = last.chunk_start_offset + last.chunk_length - 100  # inside the compressed data
    data = bytearray(recording.read_bytes())
    data[offset] ^= 0xFF
    recording.write_bytes(bytes(data))


class _FaultAt(NullObserver):
    """A rig fault once the given step has recorded (its file is written meanwhile)."""

    def __init__(self, step_id: str) -> None:
        self.step_id = step_id

    def step_started(self, step: PlannedStep) -> None:
        if step.id == self.step_id:
            raise RigFault("table: encoder fault (the test)")

    def step_samples(self, step: PlannedStep, table: SampledLog, daq: SampledLog) -> None:
        return None


def test_the_child_is_reaped_after_a_rig_fault(tmp_path: Path,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    started: list[EarlyAnalysis] = []
    real = EarlyAnalysis.__init__

    def recorded_init(self: EarlyAnalysis) -> None:
        real(self)
        started.append(self)

    monkeypatch.setattr(EarlyAnalysis, "__init__", recorded_init)
    with pytest.raises(RigFault, match="encoder fault"):
        session.run(SINES, None, tmp_path / "run", False, 1, None, show_progress=False,
                    events=RunEvents(_FaultAt("s002-sine-inner-1.9531Hz-100dps2")))
    assert len(started) == 1
    with pytest.raises(ProcessLookupError):  # reaped: no such process any more
        os.kill(started[0].pid, 0)


def test_no_child_when_switched_off_or_nothing_to_send(monkeypatch: pytest.MonkeyPatch) -> None:
    recorder = object()
    sines = session.prepare(SINES, None)
    monkeypatch.setenv(early_analysis.EARLY_ENV, "0")
    with early_analysis.early_analysis(sines.plan, recorder, sines.envelope) as early:
        assert early.analysis is None and early.recorder is recorder
    monkeypatch.delenv(early_analysis.EARLY_ENV)
    static = session.prepare(LONG_STATIC, None)
    long_only = static.plan.model_copy(update={"steps": static.plan.steps[1:]})
    assert static.envelope.streaming_daq  # the 10-minute record is streamed: never sent
    with early_analysis.early_analysis(long_only, recorder, static.envelope) as early:
        assert early.analysis is None and early.recorder is recorder
    assert [s.id for s in early_analysis.sendable(static.plan, static.envelope)] == [
        static.plan.steps[0].id]


@pytest.mark.parametrize(("threads", "kind"), [(1, process.Forked),
                                               (2, subprocess.Popen)])
def test_forked_when_alone_a_new_interpreter_beside_a_thread(
        monkeypatch: pytest.MonkeyPatch, threads: int, kind: type) -> None:
    # a fork beside another thread could copy a lock it holds: then a new interpreter
    monkeypatch.setattr(process.threading, "active_count", lambda: threads)
    early = EarlyAnalysis()
    try:
        assert isinstance(early._process, kind)
        pid = early.pid
    finally:
        early.close()
    with pytest.raises(ProcessLookupError):  # ended and reaped either way
        os.kill(pid, 0)


def test_forked_child_wait_honours_its_timeout() -> None:
    # Popen.wait(timeout) raises TimeoutExpired while the child runs; the forked handle too
    pid = os.fork()
    if pid == 0:  # the child: sleeps past the first wait's timeout, then exits with 3
        time.sleep(0.5)
        os._exit(3)
    forked = process.Forked(pid)
    with pytest.raises(subprocess.TimeoutExpired):
        forked.wait(0.05)
    assert forked.poll() is None  # still running: the timeout did not reap or kill it
    assert forked.wait(10.0) == 3
    assert forked.wait() == 3  # reaped once; the status is kept
