"""Locations: local paths stay paths; URLs name objects on a real S3-compatible server."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from recording_data import run_meta, sine_step, step_logs

from aatest.engine.errors import EXIT_BAD_INPUT
from aatest.recording import RunRecorder, read_dataset
from aatest.storage import FETCHED, RemotePath, StorageError, locate, require, upload_dir
from aatest.storage.location import RANDOM_BLOCK_BYTES


def test_local_paths_and_file_urls_stay_paths(tmp_path: Path) -> None:
    assert locate(str(tmp_path)) == tmp_path
    assert locate(f"file://{tmp_path}") == tmp_path
    assert locate(tmp_path) is tmp_path
    where = locate("s3://bucket/runs/r1/")
    assert isinstance(where, RemotePath) and str(where) == "s3://bucket/runs/r1"
    assert str(where / "steps" / "run.json") == "s3://bucket/runs/r1/steps/run.json"
    assert str(where.with_name("r2")) == "s3://bucket/runs/r2"
    assert where.name == "r1" and (where / "recording.mcap").suffix == ".mcap"


def test_unknown_scheme_is_bad_input_naming_it() -> None:
    with pytest.raises(StorageError, match="nosuchscheme://x/y: unknown storage scheme") as caught:
        locate("nosuchscheme://x/y").exists()
    assert caught.value.exit_code == EXIT_BAD_INPUT


def test_missing_bucket_and_object_are_bad_input_naming_the_url(bucket: str) -> None:
    with pytest.raises(StorageError, match=r"s3://no-such-bucket-x/r1: bucket 'no-such-bucket-x'"):
        require(locate("s3://no-such-bucket-x/r1"))
    with pytest.raises(StorageError, match=rf"s3://{bucket}/absent: no such object"):
        require(locate(f"s3://{bucket}/absent"))


def test_options_come_from_the_environment(bucket: str, monkeypatch: pytest.MonkeyPatch
                                           ) -> None:
    endpoint = os.environ["AATEST_S3_ENDPOINT"]
    monkeypatch.delenv("AATEST_S3_ENDPOINT")
    monkeypatch.setenv("AWS_ENDPOINT_URL", endpoint)  # the fallback reaches the same server
    assert require(locate(f"s3://{bucket}")) == locate(f"s3://{bucket}")
    monkeypatch.setenv("AATEST_STORAGE_OPTIONS", "{not json")
    with pytest.raises(StorageError, match=rf"s3://{bucket}/x: AATEST_STORAGE_OPTIONS: not a JSON"):
        locate(f"s3://{bucket}/x").exists()


def test_objects_round_trip_and_list_below_a_prefix(bucket: str, tmp_path: Path) -> None:
    (tmp_path / "steps").mkdir()
    (tmp_path / "results.json").write_text("{}")
    (tmp_path / "report.html.sig").write_text("sig")
    (tmp_path / "steps" / "0001.mcap").write_bytes(b"\x00" * 10)
    (tmp_path / "run.lock").write_text("pid")
    remote = locate(f"s3://{bucket}/runs/r1")
    assert isinstance(remote, RemotePath)
    uploaded = upload_dir(tmp_path, remote)
    assert uploaded[-1] == "report.html.sig", "the signature goes up last"
    assert "run.lock" not in uploaded, "a run's lock never leaves the machine"
    assert remote.members() == ["report.html.sig", "results.json", "steps/0001.mcap"]
    assert remote.is_dir() and (remote / "results.json").is_file()
    assert (remote / "steps" / "0001.mcap").read_bytes() == b"\x00" * 10
    (remote / "results.json").write_text('{"a": 1}')
    assert (remote / "results.json").read_text() == '{"a": 1}'


def test_reading_one_step_fetches_a_fraction_of_the_recording(bucket: str, tmp_path: Path
                                                             ) -> None:
    """Streaming, measured: the bytes fsspec's cache requested from the server while the
    header, summary and one step's logs were read, against the object's size."""
    steps = [sine_step(f"s{i:02d}", 65536) for i in range(1, 9)]
    recorder = RunRecorder(tmp_path)
    recorder.write_run_metadata(run_meta(steps))
    logs = {}
    for seed, step in enumerate(steps):
        logs[step.id] = step_logs(step, seed)
        recorder.write_step(step, *logs[step.id])
    recording = recorder.finalize()
    remote = locate(f"s3://{bucket}/runs/big")
    assert isinstance(remote, RemotePath)
    upload_dir(tmp_path, remote)
    size = (remote / "recording.mcap").size_bytes()
    assert size == recording.stat().st_size and size > 16 * RANDOM_BLOCK_BYTES
    before = FETCHED["bytes"]
    dataset = read_dataset(str(remote))
    third = dataset.steps[2]
    np.testing.assert_array_equal(third.daq["v_sz"], logs["s03"][1]["v_sz"])
    fetched = FETCHED["bytes"] - before
    # one step of eight plus the summary and at most two read-ahead blocks per file opening
    # (summary, then the step's chunks): well under a third of the object
    assert fetched < size / 3, (fetched, size)
    assert fetched >= size / 8 * 0.9, "the step's own chunks were read"
    assert str(dataset.source) == f"{remote}/recording.mcap"
