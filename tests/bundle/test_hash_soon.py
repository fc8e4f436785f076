"""A file hashed as soon as it is written (:func:`aatest.bundle.manifest.hash_soon`): the
digest :func:`file_sha256` gives is that of the file's bytes, and a file changed since is
hashed anew."""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import pytest

from aatest.bundle import manifest
from aatest.bundle.manifest import file_sha256, hash_soon


def test_the_digest_made_ahead_is_the_files(tmp_path: Path) -> None:
    path = tmp_path / "recording.mcap"
    data = os.urandom(3 << 20)  # three 1 MiB reads
    path.write_bytes(data)
    thread = hash_soon(path)
    assert thread is not None
    thread.join()
    assert file_sha256(path) == hashlib.sha256(data).hexdigest()
    assert hash_soon(tmp_path / "missing.mcap") is None
    assert hash_soon(path) is None  # hashed already: its digest serves


def test_a_failed_hash_is_not_kept(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = _written(tmp_path / "recording.mcap", b"data")

    def unreadable(_path: Path) -> str:
        raise OSError("read error")

    monkeypatch.setattr(manifest, "_read_sha256", unreadable)
    thread = hash_soon(path)
    assert thread is not None
    thread.join()
    monkeypatch.undo()
    assert file_sha256(path) == hashlib.sha256(b"data").hexdigest()  # read again


def test_a_file_changed_after_it_was_hashed_is_hashed_again(tmp_path: Path) -> None:
    path = tmp_path / "recording.mcap"
    path.write_bytes(b"first bytes")
    thread = hash_soon(path)
    assert thread is not None
    thread.join()
    os.replace(_written(tmp_path / "other", b"other bytes"), path)  # a new file, same name
    assert file_sha256(path) == hashlib.sha256(b"other bytes").hexdigest()
    with path.open("r+b") as f:  # the same file written in place: its size and mtime change
        f.write(b"OTHER BYTES, longer")
    assert file_sha256(path) == hashlib.sha256(b"OTHER BYTES, longer").hexdigest()


def test_only_the_latest_digests_are_kept(tmp_path: Path) -> None:
    for i in range(manifest._SOON_KEPT + 3):
        thread = hash_soon(_written(tmp_path / f"f{i}", bytes([i])))
        assert thread is not None
        thread.join()
    assert len(manifest._SOON) == manifest._SOON_KEPT


def _written(path: Path, data: bytes) -> Path:
    path.write_bytes(data)
    return path
