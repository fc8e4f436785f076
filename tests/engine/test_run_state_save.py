"""The run state file is replaced atomically on every change, and only on a change."""

from __future__ import annotations

import json
from pathlib import Path

from aatest.engine.run.run_state import STATE_FILE, RunState, open_state


def test_an_unchanged_state_is_not_written_again(tmp_path: Path) -> None:
    state = open_state(tmp_path, "p", "abc", 3, False)
    state.save(tmp_path)
    path = tmp_path / STATE_FILE
    written = path.stat().st_ino  # each write renames a new file into place
    state.save(tmp_path)
    assert path.stat().st_ino == written
    state.chamber_steps_done.append("c1")  # a change in place is seen
    state.save(tmp_path)
    assert path.stat().st_ino != written
    assert RunState.load(tmp_path).chamber_steps_done == ["c1"]


def test_a_deleted_state_file_is_written_again(tmp_path: Path) -> None:
    state = open_state(tmp_path, "p", "abc", 3, False)
    state.save(tmp_path)
    (tmp_path / STATE_FILE).unlink()
    state.save(tmp_path)
    assert json.loads((tmp_path / STATE_FILE).read_text())["seed"] == 3
