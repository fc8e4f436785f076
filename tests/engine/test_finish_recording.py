"""The end of a run's record phase (:func:`aatest.engine.run.session.finish_recording`): the
figures' processes start there when the early analysis ran, and not without it."""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

import pytest

from aatest.early.analysis import EarlyResults
from aatest.engine.run import session
from aatest.parallel import aside, forked
from aatest.parallel.forked import WORKERS_ENV
from aatest.presentation.figures import drawing_aside


class _Recorder:
    """A recorder whose merge writes a small file (the hashing reads it)."""

    def __init__(self, run_dir: Path) -> None:
        self.path = run_dir / "recording.mcap"

    def finalize(self) -> Path:
        self.path.write_bytes(b"merged")
        return self.path


class _Early:
    def __init__(self, made: EarlyResults | None) -> None:
        self.made = made

    def results(self) -> EarlyResults | None:
        return self.made


@pytest.fixture(autouse=True)
def _two_workers(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(WORKERS_ENV, "2")
    stray = set(threading.enumerate())
    monkeypatch.setattr(forked, "_other_threads", lambda: [
        t.name for t in threading.enumerate()
        if t not in stray and t is not threading.current_thread()])
    if forked.cpu_workers() < 2:
        pytest.skip("this machine gives the tests one CPU: no process is started aside there")


@pytest.mark.parametrize(("made", "started"), [(EarlyResults({}, []), 1), (None, 0)],
                         ids=["early-analysis", "none"])
def test_the_figures_processes_start_when_the_early_analysis_ran(
        tmp_path: Path, made: Any, started: int) -> None:
    with drawing_aside():
        assert session.finish_recording(_Recorder(tmp_path), _Early(made)) is made
        block = aside._SLOT.block
        assert block is not None and len(block.started) == started
