"""Object storage failing in the middle of a read: a clear error naming the URL (exit 2).

An object that disappears after it was opened, or a server that stops answering, used to
surface as whatever the S3 client raised (``FileNotFoundError``, aiohttp's disconnection
errors) and end the CLI as an internal error (exit 4, a crash report). The reads of an open
object now fail as :class:`~aatest.storage.StorageError`, like every other unreachable input.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from recording_data import run_meta, sine_step, step_logs
from s3_server import moto_server, new_bucket, use_server

from aatest.engine.errors import EXIT_BAD_INPUT, AatestError
from aatest.recording import RunRecorder, read_dataset
from aatest.storage import RemotePath, StorageError, locate, upload_dir
from aatest.storage.location import RANDOM_BLOCK_BYTES


def _object(bucket: str, size_blocks: int = 8) -> RemotePath:
    """An object several read-ahead blocks long (a later block needs a new ranged GET)."""
    remote = locate(f"s3://{bucket}/big.bin")
    assert isinstance(remote, RemotePath)
    rng = np.random.default_rng(3)
    remote.write_bytes(rng.integers(0, 256, size_blocks * RANDOM_BLOCK_BYTES, np.uint8).tobytes())
    return remote


def test_object_deleted_mid_read_is_bad_input_naming_it(bucket: str) -> None:
    remote = _object(bucket)
    with remote.open("rb") as handle:
        assert len(handle.read(1024)) == 1024
        remote.unlink()
        handle.seek(6 * RANDOM_BLOCK_BYTES)
        with pytest.raises(StorageError, match=rf"{remote}: the object disappeared") as caught:
            handle.read(1024)
    assert caught.value.exit_code == EXIT_BAD_INPUT


@pytest.mark.slow  # ≈ 7 s: a server of its own, and s3fs's retries before it gives up
def test_server_gone_mid_read_is_bad_input_naming_the_url(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    with moto_server() as endpoint:  # a server of this test's own, stopped in the middle
        use_server(monkeypatch, endpoint, tmp_path)
        remote = _object(new_bucket())
        handle = remote.open("rb")
        assert len(handle.read(1024)) == 1024
    try:
        handle.seek(6 * RANDOM_BLOCK_BYTES)
        with pytest.raises(StorageError, match=rf"{remote}: ") as caught:
            handle.read(1024)
        assert caught.value.exit_code == EXIT_BAD_INPUT
    finally:
        handle.close()


def test_recording_deleted_after_opening_is_bad_input(bucket: str, tmp_path: Path) -> None:
    """The reader opened the recording (header and summary); its steps' chunks are gone."""
    steps = [sine_step(f"s{i:02d}", 8192) for i in range(1, 5)]
    recorder = RunRecorder(tmp_path)
    recorder.write_run_metadata(run_meta(steps))
    for seed, step in enumerate(steps):
        recorder.write_step(step, *step_logs(step, seed))
    recorder.finalize()
    remote = locate(f"s3://{bucket}/runs/gone")
    assert isinstance(remote, RemotePath)
    upload_dir(tmp_path, remote)
    dataset = read_dataset(str(remote))
    (remote / "recording.mcap").unlink()
    with pytest.raises(AatestError, match=rf"{remote}/recording.mcap: not found") as caught:
        _ = dataset.steps[2].daq["v_sz"]
    assert caught.value.exit_code == EXIT_BAD_INPUT
