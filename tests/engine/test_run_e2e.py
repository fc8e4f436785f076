"""A whole run through the CLI, a SIGKILL in the middle of it, and ``--resume``."""

import hashlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader

HERE = Path(__file__).parent
REPO = HERE.parents[1]
QUICK = REPO / "tests" / "data" / "procedures" / "quick-sine-3-steps.yaml"
SWEEP = HERE / "data" / "resume-sweep.yaml"


def aatest(*args: str, timeout: float = 300) -> subprocess.CompletedProcess[str]:
    cmd = [sys.executable, "-m", "aatest.cli", *args]
    return subprocess.run(
        cmd, capture_output=True, text=True, timeout=timeout, stdin=subprocess.DEVNULL, check=False
    )


def _steps_on_disk(run_dir: Path) -> list[Path]:
    return sorted((run_dir / "steps").glob("*.mcap")) if (run_dir / "steps").exists() else []


def _recorded_step_ids(recording: Path) -> list[str]:
    """Step ids in the recording, read with the plain mcap reader (no aatest code)."""
    with recording.open("rb") as fh:
        reader = make_reader(fh)
        ids = []
        for record in reader.iter_metadata():
            if record.name == "step":
                ids.append(json.loads(record.metadata["step"])["id"])
        messages = sum(1 for _ in reader.iter_messages())
    assert messages > 0
    return ids


def test_quick_run_produces_recording_results_and_report(tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    done = aatest("run", str(QUICK), "--out", str(run_dir), "--no-progress", "--seed", "3")
    assert done.returncode == 0, done.stderr
    results = json.loads((run_dir / "results.json").read_text())
    assert set(results) >= {
        "procedure", "rig", "steps", "analysis", "lab_duration_s", "wall_duration_s"
    }
    assert len(results["steps"]) == 3 and results["analysis_errors"] == {}
    # the twin's sensor: ≈ −48 dB (°/s² → V) at low frequency, as measured (docs/method.md §1.3)
    gains = [p["gain_db"] for p in results["analysis"]["frf"]["v_sz"]]
    assert gains[0] == pytest.approx(-47.9, abs=0.3)
    assert (run_dir / "report.html").stat().st_size > 1000
    assert len(_recorded_step_ids(run_dir / "recording.mcap")) == 3
    assert _steps_on_disk(run_dir) == [], "per-step copies are pruned once merged"


def test_resuming_a_finished_run_only_analyses_again(tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    assert aatest("run", str(QUICK), "--out", str(run_dir), "--no-progress").returncode == 0
    before = hashlib.sha256((run_dir / "recording.mcap").read_bytes()).hexdigest()
    again = aatest("run", str(QUICK), "--out", str(run_dir), "--resume", "--no-progress")
    assert again.returncode == 0, again.stderr
    assert hashlib.sha256((run_dir / "recording.mcap").read_bytes()).hexdigest() == before
    assert len(json.loads((run_dir / "results.json").read_text())["steps"]) == 3


def test_sigkill_mid_step_then_resume_records_every_step_once(tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    cmd = [sys.executable, "-m", "aatest.cli", "run", str(SWEEP), "--out", str(run_dir),
           "--no-progress", "--seed", "5"]
    proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 120
    while len(_steps_on_disk(run_dir)) < 3 and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.01)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=30)
    completed_before = len(_steps_on_disk(run_dir))
    assert 3 <= completed_before < 8, "the kill must land before the run finished"
    assert not (run_dir / "results.json").exists()

    resumed = aatest("run", str(SWEEP), "--out", str(run_dir), "--resume", "--no-progress")
    assert resumed.returncode == 0, resumed.stderr
    ids = _recorded_step_ids(run_dir / "recording.mcap")
    assert len(ids) == 8 and len(set(ids)) == 8
    results = json.loads((run_dir / "results.json").read_text())
    assert [s["id"] for s in results["steps"]] == ids
    assert len(results["analysis"]["frf"]["v_sz"]) == 8
    assert _steps_on_disk(run_dir) == []


def test_resume_refuses_a_changed_procedure(tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    assert aatest("run", str(QUICK), "--out", str(run_dir), "--no-progress").returncode == 0
    changed = tmp_path / "changed.yaml"
    changed.write_text(QUICK.read_text().replace("T0001", "T0002"))
    again = aatest("run", str(changed), "--out", str(run_dir), "--resume", "--no-progress")
    assert again.returncode == 2 and "procedure file changed" in again.stderr
