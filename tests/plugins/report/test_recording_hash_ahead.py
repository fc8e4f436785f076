"""The recording hash made ahead on a thread is the one made at render time."""

from __future__ import annotations

import os
import threading
from pathlib import Path

from aatest.bundle import manifest
from aatest.bundle.signing import file_sha256
from aatest.plugins.report.traceability import RECORDING_FILE, hashed_ahead, recording_hash


def _threads() -> set[str]:
    return {t.name for t in threading.enumerate()}


def test_digest_made_ahead_is_the_files(tmp_path: Path) -> None:
    path = tmp_path / RECORDING_FILE
    path.write_bytes(os.urandom(3 * 2**20 + 17))  # more than one read chunk
    key = manifest._identity(path)
    with hashed_ahead(tmp_path):
        assert key in manifest._SOON  # the digest is being made
        assert recording_hash(tmp_path) == file_sha256(path)
    assert manifest._SOON[key].done()  # made by the end of the block
    assert "aatest-hash-soon" not in _threads()  # the thread ended with the block


def test_a_file_changed_after_the_start_is_hashed_again(tmp_path: Path) -> None:
    path = tmp_path / RECORDING_FILE
    path.write_bytes(b"first")
    with hashed_ahead(tmp_path):
        path.unlink()
        path.write_bytes(b"second, longer")  # another inode and size
        assert recording_hash(tmp_path) == file_sha256(path)


def test_without_a_recording_nothing_is_hashed(tmp_path: Path) -> None:
    (tmp_path / RECORDING_FILE).mkdir()  # not a file
    with hashed_ahead(tmp_path):
        assert manifest._identity(tmp_path / RECORDING_FILE) is None  # nothing to hash
        assert "aatest-hash-soon" not in _threads()
        assert recording_hash(tmp_path) == "no recording.mcap in the run directory"


def test_nested_blocks_hash_once(tmp_path: Path) -> None:
    path = tmp_path / RECORDING_FILE
    path.write_bytes(b"data")
    key = manifest._identity(path)
    with hashed_ahead(tmp_path):
        outer = manifest._SOON[key]
        with hashed_ahead(tmp_path):
            assert manifest._SOON[key] is outer  # the inner block started no second hash
        assert manifest._SOON[key] is outer  # the inner block leaves the outer's digest
        assert recording_hash(tmp_path) == file_sha256(path)


def test_a_plugin_preparing_without_run_dir_still_prepares(tmp_path: Path) -> None:
    from aatest.engine.run import session

    calls: list[str] = []

    class Old:
        def preparing(self) -> object:
            calls.append("old")
            return threading.Lock()  # any context manager

    class New:
        def preparing(self, run_dir: Path | None = None) -> object:
            calls.append(f"new {run_dir}")
            return threading.Lock()

    with session._preparing(Old(), tmp_path), session._preparing(New(), tmp_path):
        pass
    assert calls == ["old", f"new {tmp_path}"]
