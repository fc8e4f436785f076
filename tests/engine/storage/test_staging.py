"""A run bound for object storage: killed mid-run, nothing recorded is lost; resumed, it
completes and goes up whole."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from aatest.engine.storage import RemotePath, locate, staging_dir

SWEEP = Path(__file__).parents[1] / "data" / "resume-sweep.yaml"


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
    from aatest.engine.recording import read_dataset

    ids = [s.step.id for s in read_dataset(url).steps]
    assert len(ids) == 8 and len(set(ids)) == 8, "every step recorded once, none lost"
