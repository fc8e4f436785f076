"""``aatest batch analyze s3://…``: the twin archive on a real S3-compatible server (moto's
server mode on loopback), re-analysed by a local Dask cluster of worker processes.

The workers read the recordings from the server themselves (the endpoint and credentials reach
them through the environment, as they would on a lab's cluster); the results must equal the
certificates' own values for the same recordings, and a re-run must skip every one.
Slow (two batches on worker processes): run with ``-m slow``.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from batch_units import ARCHIVE_UNITS
from s3_server import moto_server, new_bucket, use_server

from aatest.records.models import RecordFilter
from aatest.records.store import RecordStore
from aatest.storage import locate
from aatest.storage.location import RemotePath
from aatest.storage.staging import upload_dir

TIMEOUT_S = 600.0


@pytest.fixture(scope="module")
def endpoint() -> Iterator[str]:
    with moto_server() as url:
        yield url


def _batch(prefix: str, records: str) -> tuple[int, dict]:
    done = subprocess.run(
        [sys.executable, "-c", "from aatest.cli import main; main()", "batch", "analyze",
         prefix, "--records", records, "--workers", "2", "--json"],
        capture_output=True, text=True, timeout=TIMEOUT_S, check=False)
    assert done.returncode in (0, 1), done.stderr[-3000:]
    return done.returncode, json.loads(done.stdout)


@pytest.mark.slow  # two batches on a cluster of worker processes: ≈ 1 min on 2 idle cores
def test_archive_on_s3_reanalyses_on_a_local_cluster(
        endpoint: str, twin_archive: tuple[Path, Path], store_copy: str,
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    use_server(monkeypatch, endpoint, tmp_path)
    bucket = new_bucket()
    root, _ = twin_archive
    remote = locate(f"s3://{bucket}/archive")
    assert isinstance(remote, RemotePath)
    runs = sorted(p.parent for p in root.rglob("recording.mcap"))
    assert len(runs) == len(ARCHIVE_UNITS)
    for run in runs:
        upload_dir(run, remote.joinpath(*run.relative_to(root).parts))

    code, report = _batch(f"s3://{bucket}/archive", store_copy)
    assert report["failures"] == [] and report["skipped"] == 0
    assert len(report["completed"]) == len(ARCHIVE_UNITS)
    # every subject is the recording's own URL on the server: nothing was read locally
    assert all(r["recording"].startswith(f"s3://{bucket}/archive/") for r in report["results"])
    with RecordStore.open(store_copy) as store:
        certified = {Path(r.bundle).parent.relative_to(root).as_posix(): r
                     for r in store.query(RecordFilter(include_simulations=True))}
    for result in report["results"]:
        relative = result["recording"].removeprefix(f"s3://{bucket}/archive/")
        record = certified[relative.removesuffix("/recording.mcap")]
        # same recording bytes, same code: only BLAS summation order may differ between the
        # coordinator that certified it and a single-threaded worker — 1e-9 relative is far
        # above that (a handful of ulps through a least-squares fit of 6 000 samples)
        assert result["quantities"]["scale_factor.v_sz"]["value"] == pytest.approx(
            record.quantities["scale_factor.v_sz"].value, rel=1e-9)
        assert result["overall_verdict"] == record.overall_verdict
    expected_code = 1 if any(r["overall_verdict"] == "fail" for r in report["results"]) else 0
    assert code == expected_code

    _, again = _batch(f"s3://{bucket}/archive", store_copy)
    assert again["skipped"] == len(ARCHIVE_UNITS) and again["completed"] == []
