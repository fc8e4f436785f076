"""The end of a run's record phase (:func:`aatest.engine.run.session.finish_recording`): the
figures' processes start there when the early analysis made all it was sent, and not when its
child was still at work or there was none."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from aatest.early.analysis import EarlyResults
from aatest.engine.run import session
from aatest.parallel import aside
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


@pytest.mark.usefixtures("two_workers")
@pytest.mark.parametrize(("made", "started"), [
    (EarlyResults({}, [], complete=True), 1), (EarlyResults({}, []), 0), (None, 0)],
    ids=["all-made-early", "child-still-at-work", "no-early-analysis"])
def test_the_figures_processes_start_when_the_early_analysis_made_all(
        tmp_path: Path, made: Any, started: int) -> None:
    with drawing_aside():
        assert session.finish_recording(_Recorder(tmp_path), _Early(made)) is made
        block = aside._SLOT.block
        assert block is not None and len(block.started) == started
