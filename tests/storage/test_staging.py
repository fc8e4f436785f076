"""A run bound for object storage: killed mid-run, nothing recorded is lost; resumed, it
completes and goes up whole."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from aatest.storage import RemotePath, locate, staging_dir

SWEEP = Path(__file__).parents[1] / "engine" / "data" / "resume-sweep.yaml"


def aatest(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "aatest.cli", *args], capture_output=True,
                          text=True, timeout=600, stdin=subprocess.DEVNULL, check=False)


def _steps(folder: Path) -> list[Path]:
    return sorted((folder / "steps").glob("*.mcap")) if (folder / "steps").is_dir() else []


def test_staging_directory_depends_only_on_the_url(s3_env: str) -> None:
    one, same, two = (locate(u) for u in ("s3://b/runs/r1", "s3://b/runs/r1/", "s3://b/runs/r2"))
    assert isinstance(one, RemotePath) and isinstance(same, RemotePath)
    assert isinstance(two, RemotePath)
    assert staging_dir(one) == staging_dir(same)
    assert staging_dir(one) != staging_dir(two)
    assert staging_dir(one).parent == Path(os.environ["AATEST_STAGING"])


def test_a_killed_run_to_s3_stays_local_and_resumes_to_s3(bucket: str) -> None:
    url = f"s3://{bucket}/runs/sweep"
    remote = locate(url)
    assert isinstance(remote, RemotePath)
    local = staging_dir(remote)
    cmd = [sys.executable, "-m", "aatest.cli", "run", str(SWEEP), "--out", url,
           "--no-progress", "--seed", "5"]
    proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 300
    while len(_steps(local)) < 3 and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.01)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=30)
    recorded = len(_steps(local))
    assert 3 <= recorded < 8, "the kill must land before the run finished"
    assert remote.members() == [], "nothing goes up before the run has finished"

    resumed = aatest("run", str(SWEEP), "--out", url, "--resume", "--no-progress")
    assert resumed.returncode == 0, resumed.stderr
    assert not local.exists(), "the staging copy goes once the bundle is uploaded"
    assert {"recording.mcap", "results.json", "report.html"} <= set(remote.members())
    from aatest.recording import read_dataset

    ids = [s.step.id for s in read_dataset(url).steps]
    assert len(ids) == 8 and len(set(ids)) == 8, "every step recorded once, none lost"


QUICK = Path(__file__).parents[1] / "data" / "procedures" / "quick-sine-3-steps.yaml"


def test_a_failed_upload_keeps_the_run_and_resume_uploads_it(
        bucket: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """The connection drops while the finished bundle goes up (injected into aatest's upload
    step, after the first object): exit 2, the run stays whole in staging, nothing is
    registered; ``--resume`` uploads and registers it."""
    from typer.testing import CliRunner

    from aatest.cli import app
    from aatest.storage import StorageError, staging

    url = f"s3://{bucket}/runs/quick"
    remote = locate(url)
    assert isinstance(remote, RemotePath)
    real_upload = staging.upload_dir

    def dropped(local: Path, target: RemotePath) -> list[str]:
        first = next(p for p in sorted(local.iterdir()) if p.is_file())
        target.fs.put_file(str(first), (target / first.name).path)
        raise StorageError(f"{target / 'recording.mcap'}: connection reset (injected)")

    monkeypatch.setattr(staging, "upload_dir", dropped)
    runner = CliRunner()
    failed = runner.invoke(app, ["run", str(QUICK), "--out", url, "--no-progress"])
    assert failed.exit_code == 2 and "connection reset (injected)" in failed.stderr
    local = staging_dir(remote)
    assert (local / "recording.mcap").is_file() and (local / "results.json").is_file()
    assert "report.html.sig" not in remote.members() and "report.html" not in remote.members()
    listed = runner.invoke(app, ["records", "list", "--include-simulations"])
    assert "quick" not in listed.stdout, "nothing registered for a bundle that did not go up"

    monkeypatch.setattr(staging, "upload_dir", real_upload)
    resumed = runner.invoke(app, ["run", str(QUICK), "--out", url, "--resume", "--no-progress"])
    assert resumed.exit_code == 0, resumed.stderr
    assert not local.exists()
    assert {"recording.mcap", "results.json", "report.html"} <= set(remote.members())
    listed = runner.invoke(app, ["records", "list", "--include-simulations"])
    assert f"{remote}/report.html" in listed.stdout
