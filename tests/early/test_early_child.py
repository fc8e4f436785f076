"""The early analysis's child work, in this process: each step file made as the pass makes
that step of the merged recording, taken only where the recorded bytes are the same."""

from __future__ import annotations

import logging
import threading
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from recording_data import run_meta, sine_step, step_logs

from aatest.early.analysis import EarlyResults
from aatest.early.child import _Child, _Later
from aatest.early.made import LaterMade
from aatest.engine.analysis.passes import run_analyses
from aatest.engine.registry import pinned
from aatest.recording import RunRecorder, read_dataset
from aatest.recording.step_chunks import step_digests

ANALYSIS = ["sync", "frf"]


def _record(run_dir: Path) -> tuple[RunRecorder, list[Any]]:
    """Three synthetic sine steps, each written to its step file (not merged yet)."""
    steps = [sine_step(f"s{i:02d}", samples=8192) for i in range(1, 4)]
    recorder = RunRecorder(run_dir)
    recorder.write_run_metadata({**run_meta(steps), "analysis": ANALYSIS})
    for seed, step in enumerate(steps):
        recorder.write_step(step, *step_logs(step, seed))
    return recorder, steps


def _made(recorder: RunRecorder, steps: list[Any]) -> EarlyResults:
    """What the child makes of each step file, as it arrives."""
    child = _Child()
    files = dict(zip([s.id for s in steps], recorder.step_files(), strict=True))
    made = {step_id: child.analyse(step_id, path) for step_id, path in files.items()}
    assert all(m is not None for m in made.values())
    return EarlyResults({k: v for k, v in made.items() if v is not None})


def _analysed(run_dir: Path, early: EarlyResults | None, analysis: list[str] | None = None
              ) -> dict[str, Any]:
    data = read_dataset(run_dir)
    if early is not None:
        early.offer(data)
    done = run_analyses(data, analysis or ANALYSIS)
    assert not done.errors
    return {"values": {k: v.model_dump(mode="json") for k, v in done.values.items()},
            "figures": done.figures}


def test_steps_made_by_the_child_give_the_same_results(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    with pinned():
        recorder, steps = _record(tmp_path)
        early = _made(recorder, steps)
        recorder.finalize()
        assert {k: m.digest for k, m in early.made.items()} == step_digests(
            tmp_path / "recording.mcap")  # merged verbatim: the same bytes
        caplog.set_level(logging.DEBUG, "aatest.analysis")
        plain = _analysed(tmp_path, None)
        taken = _analysed(tmp_path, early)
    assert early.offered == 3
    assert [r.getMessage() for r in caplog.records if "sync pass" in r.getMessage()] == [
        "sync pass: 0 of 3 steps taken as analysed while the run recorded",
        "sync pass: 3 of 3 steps taken as analysed while the run recorded"]
    assert taken == plain  # every value and figure


def test_a_step_recorded_again_after_the_child_read_it_is_computed_again(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    with pinned():
        recorder, steps = _record(tmp_path)
        early = _made(recorder, steps)
        recorder.write_step(steps[1], *step_logs(steps[1], seed=11))  # other samples, same id
        recorder.finalize()
        caplog.set_level(logging.DEBUG, "aatest.analysis")
        plain = _analysed(tmp_path, None)
        taken = _analysed(tmp_path, early)
    assert early.offered == 2
    assert "sync pass: 2 of 3 steps taken" in caplog.text
    assert taken == plain


def test_a_taken_steps_warnings_are_raised_where_the_pass_takes_it(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # the pass computing a step would have warned; taking the child's result must too
    from aatest.plugins.analysis.sync import SyncAnalysis

    real = SyncAnalysis.early_step

    def warning_early_step(data: Any, index: int) -> Any:
        warnings.warn(f"step {index} looks odd", RuntimeWarning, stacklevel=1)
        return real(data, index)

    monkeypatch.setattr(SyncAnalysis, "early_step", staticmethod(warning_early_step))
    with pinned():
        recorder, steps = _record(tmp_path)
        early = _made(recorder, steps)
        recorder.finalize()
        assert [[w.message for w in m.warned] for m in early.made.values()] == [
            ["step 0 looks odd"], ["step 1 looks odd"], ["step 2 looks odd"]]
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            early.offer(read_dataset(tmp_path))
    assert early.offered == 3
    assert [(w.category, str(w.message)) for w in caught] == [
        (RuntimeWarning, f"step {i} looks odd") for i in range(3)]
    assert {Path(w.filename).name for w in caught} == {Path(__file__).name}  # where raised


def _two_groups(run_dir: Path) -> tuple[RunRecorder, list[Any]]:
    """Two test groups of six coherent sine frequencies each (what a transfer-function
    model needs), each step written to its step file (not merged yet)."""
    base = sine_step(samples=8192)
    steps = [base.model_copy(update={
        "id": f"s{k:02d}-{group}", "group": group, "cycles": cycles,
        "frequency_hz": cycles * base.sample_rate_hz / base.samples,
        "amplitude_deg": 100.0 / (2 * np.pi * cycles * base.sample_rate_hz / base.samples) ** 2})
        for k, (group, cycles) in enumerate((g, c) for g in ("g1", "g2")
                                            for c in (4, 6, 8, 11, 16, 23))]
    recorder = RunRecorder(run_dir)
    recorder.write_run_metadata({**run_meta(steps), "analysis": TF_ANALYSIS})
    for seed, step in enumerate(steps):
        recorder.write_step(step, *step_logs(step, seed))
    return recorder, steps


TF_ANALYSIS = ["sync", "frf", "transfer_function"]


def _made_with_later(recorder: RunRecorder, steps: list[Any]
                     ) -> tuple[EarlyResults, dict[str, int]]:
    """What the child makes of each step file as it arrives, and of the work offered once a
    group's steps are all made (every piece made before the next step, as when the child has
    time to spare); and how many pieces were made after each step."""
    made_later: list[LaterMade] = []
    later = _Later(lambda message: made_later.append(message) is None)
    child = _Child(later)
    made: dict[str, Any] = {}
    pieces: dict[str, int] = {}
    for step, path in zip(steps, recorder.step_files(), strict=True):
        made[step.id] = child.analyse(step.id, path)
        pieces[step.id] = 0
        while later.pending:
            assert later.advance()
            pieces[step.id] += 1
    return EarlyResults(made, made_later), pieces


def test_group_fits_made_by_the_child_are_taken_with_the_same_results(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    # the child fits a group once it has made the group's last step, in pieces between
    # steps; the pass takes those fits (digest of the very inputs) and draws only the figures
    with pinned():
        recorder, steps = _two_groups(tmp_path)
        early, pieces = _made_with_later(recorder, steps)
        recorder.finalize()
        caplog.set_level(logging.DEBUG, "aatest.analysis")
        plain = _analysed(tmp_path, None, TF_ANALYSIS)
        taken = _analysed(tmp_path, early, TF_ANALYSIS)
    assert [m.key for m in early.later] == ["v_sz:g1", "v_sz:g2"]
    assert {k for k, n in pieces.items() if n} == {"s05-g1", "s11-g2"}  # each group's last
    assert pieces["s05-g1"] > 20  # a candidate fit each (a few ms), not one long block
    fits = [r.getMessage() for r in caplog.records if "group fits" in r.getMessage()]
    assert fits == ["transfer function: 0 of 4 group fits made while the run recorded",
                    "transfer function: 4 of 4 group fits made while the run recorded"]
    assert taken == plain  # every value and figure


def test_a_group_fit_of_other_inputs_is_not_taken(tmp_path: Path,
                                                   caplog: pytest.LogCaptureFixture) -> None:
    # a fit is taken only for the same inputs bit for bit: here step s03's FRF point is made
    # of other samples than the recording's (the step recorded again), so g1 is fitted anew
    with pinned():
        recorder, steps = _two_groups(tmp_path)
        early, _ = _made_with_later(recorder, steps)
        recorder.write_step(steps[3], *step_logs(steps[3], seed=11))
        recorder.finalize()
        caplog.set_level(logging.DEBUG, "aatest.analysis")
        plain = _analysed(tmp_path, None, TF_ANALYSIS)
        taken = _analysed(tmp_path, early, TF_ANALYSIS)
    assert early.offered == 11
    fits = [r.getMessage() for r in caplog.records if "group fits" in r.getMessage()]
    assert fits[-1] == "transfer function: 2 of 4 group fits made while the run recorded"
    assert taken == plain



def test_the_child_says_once_it_has_made_all_it_received(tmp_path: Path) -> None:
    """Idle before any step, after each step and its later work, and once only while it
    waits: the run process then knows whether the pass has anything left to make."""
    from multiprocessing import Pipe

    from aatest.early.child import serve
    from aatest.early.made import Idle, StepSent

    with pinned():
        recorder, steps = _record(tmp_path)
    files = dict(zip([s.id for s in steps], recorder.step_files(), strict=True))
    inbox, to_child = Pipe(duplex=False)
    from_child, outbox = Pipe(duplex=False)
    child = threading.Thread(target=serve, args=(inbox, outbox), daemon=True)
    child.start()
    try:
        assert from_child.recv() == Idle(0)
        to_child.send(StepSent(steps[0].id, str(files[steps[0].id])))
        step_id, made, _ = from_child.recv()
        assert step_id == steps[0].id and made is not None
        assert from_child.recv() == Idle(1)
        for step in steps[1:]:
            to_child.send(StepSent(step.id, str(files[step.id])))
        got = [from_child.recv() for _ in range(len(steps))]
        assert [m[0] for m in got if not isinstance(m, Idle)][-2:] == [s.id for s in steps[1:]]
        assert got[-1] == Idle(3) or from_child.recv() == Idle(3)
        assert not from_child.poll(0.2)  # said once; it waits
    finally:
        to_child.close()
        child.join(10)
    assert not child.is_alive()
