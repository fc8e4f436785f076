"""Operator interrupts and concurrent runs (issue 14, docs/interfaces.md §1).

SIGINT (Ctrl-C) and SIGTERM mid-step unwind through the rig's life cycle (safe stop, state
saved) and exit 3, resumable like a rig fault; a second ``run`` on a directory whose lock is
held exits 2 naming the holder's PID.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from aatest.cli import app
from aatest.engine.errors import EXIT_BAD_INPUT, EXIT_RIG_FAULT
from aatest.engine.run.run_state import LOCK_FILE, run_lock

PROCEDURE = """\
procedure: interrupts
sensor: {model: sr207, serial: "A1234"}
rig: {turntable: sim, daq: sim, chamber: none}
sampling: {rate_hz: 2000, samples: 40000, settle_s: 1}
steps:
  - multi_position: {positions: [[0, 0], [0, 180], [0, 90], [90, 90]], repetitions: 2,
                     mountings: [original]}
analysis: [sync, bias]
report: {template: calibration-certificate, sign: false}
"""
STEPS = 8


def _run_args(procedure: Path, run_dir: Path, *extra: str) -> list[str]:
    """``aatest run`` of ``procedure`` into ``run_dir``, unattended (prompts auto-confirmed)."""
    return ["run", str(procedure), "--out", str(run_dir), *extra, "--no-progress",
            "--confirm-prompts", "auto"]


#: ``python -m aatest.cli`` with the SIGINT handler an operator's terminal gives: a shell starts
#: background jobs with SIGINT ignored, children inherit that and Python then installs no
#: KeyboardInterrupt handler, so a suite run from a background job (as CI may be) would send a
#: Ctrl-C the run never sees
AATEST_AS_AT_A_TERMINAL = (
    "import runpy, signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
    "sys.argv[0] = 'aatest'; runpy.run_module('aatest.cli', run_name='__main__')")


def _aatest(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-c", AATEST_AS_AT_A_TERMINAL, *args],
        text=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )


def _first_step_file(run_dir: Path, process: subprocess.Popen[str], timeout_s: float) -> None:
    deadline = time.monotonic() + timeout_s
    while not list((run_dir / "steps").glob("001-*.mcap")):
        assert process.poll() is None, process.communicate()
        assert time.monotonic() < deadline, "the run never recorded its first step"
        time.sleep(0.01)


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_signal_mid_run_exits_3_and_resumes(tmp_path: Path, signum: signal.Signals) -> None:
    procedure, run_dir = tmp_path / "procedure.yaml", tmp_path / "run"
    procedure.write_text(PROCEDURE)
    process = _aatest(*_run_args(procedure, run_dir))
    _first_step_file(run_dir, process, timeout_s=60.0)
    process.send_signal(signum)
    _out, err = process.communicate(timeout=60)
    assert process.returncode == EXIT_RIG_FAULT, err
    lines = [line for line in err.splitlines() if line.startswith("interrupted")]
    assert lines == [
        f"interrupted ({signum.name}): the rig was brought to a safe state; continue with --resume"
    ], err
    assert "Traceback" not in err
    kept = list((run_dir / "steps").glob("*.mcap"))
    assert 1 <= len(kept) < STEPS
    assert json.loads((run_dir / "run_state.json").read_text())["finished"] is False
    resumed = _aatest(*_run_args(procedure, run_dir, "--resume"))
    out, err = resumed.communicate(timeout=120)
    assert resumed.returncode == 0, err
    assert f"{STEPS} steps" in out


def test_second_run_on_a_locked_directory_exits_2_naming_the_holder(tmp_path: Path) -> None:
    procedure, run_dir = tmp_path / "procedure.yaml", tmp_path / "run"
    procedure.write_text(PROCEDURE.replace("samples: 40000", "samples: 2000"))
    with run_lock(run_dir):  # another run (here: this process) holds the directory
        result = CliRunner().invoke(app, _run_args(procedure, run_dir))
        assert result.exit_code == EXIT_BAD_INPUT, result.output
        assert f"in use by another aatest run (PID {os.getpid()}" in result.output
        assert not (run_dir / "run_state.json").exists()  # nothing was started
    assert (run_dir / LOCK_FILE).read_text().strip() == str(os.getpid())
    result = CliRunner().invoke(app, _run_args(procedure, run_dir))
    assert result.exit_code == 0, result.output  # the lock is released with its holder


def test_concurrent_resume_exits_2(tmp_path: Path) -> None:
    """Two real processes: ``run --resume`` exits 2 while another process holds the run."""
    procedure, run_dir = tmp_path / "procedure.yaml", tmp_path / "run"
    procedure.write_text(PROCEDURE.replace("samples: 40000", "samples: 2000"))
    first = CliRunner().invoke(app, _run_args(procedure, run_dir))
    assert first.exit_code == 0, first.output
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys, time\n"
            "from pathlib import Path\nfrom aatest.engine.run.run_state import run_lock\n"
            "with run_lock(Path(sys.argv[1])):\n    print('locked', flush=True)\n"
            "    time.sleep(60)\n",
            str(run_dir),
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "locked"
        second = _aatest(*_run_args(procedure, run_dir, "--resume"))
        _out, err = second.communicate(timeout=60)
        assert second.returncode == EXIT_BAD_INPUT, err
        assert f"(PID {holder.pid}," in err
    finally:
        holder.kill()
        holder.wait(10)
