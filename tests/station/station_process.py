"""The station tests' helpers: a real station (``aatest station`` in a subprocess), the system
Chromium's path, and screenshots kept as test artefacts (``test-artifacts/station/``, ignored
by git; their paths are printed).

A module of its own, not ``conftest``: a test that imported them ``from conftest`` got
another directory's conftest when several test directories ran in one session (pytest puts
each on ``sys.path``, and the first ``conftest`` module wins).
"""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

DATA = Path(__file__).parent / "data"
ARTIFACTS = Path(__file__).parents[2] / "test-artifacts" / "station"
CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"


@dataclass
class Station:
    """A running station: its URL and the directories it reads and writes."""

    url: str
    runs: Path
    lab: Path


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _wait_listening(port: int, proc: subprocess.Popen[bytes], timeout_s: float = 30.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise RuntimeError(f"station exited early with {proc.returncode}")
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.1)
    raise RuntimeError("station did not start listening")


@contextmanager
def running_station(tmp_path: Path, *args: str,
                    env: dict[str, str] | None = None) -> Iterator[Station]:
    """``aatest station`` on a free loopback port with the reduced test procedures as lab,
    further command-line ``args`` and environment ``env``."""
    lab = tmp_path / "lab"
    shutil.copytree(DATA, lab, dirs_exist_ok=True)
    runs = tmp_path / "runs"
    port = _free_port()
    environ = {**os.environ, "AATEST_OPERATOR": "station-test", **(env or {})}
    environ.pop("AATEST_STATION_TOKEN", None)
    cmd = [sys.executable, "-m", "aatest.cli", "station", "--port", str(port),
           "--runs", str(runs), "--procedures", str(lab), *args]
    proc = subprocess.Popen(cmd, cwd=tmp_path, env=environ)
    try:
        _wait_listening(port, proc)
        yield Station(f"http://127.0.0.1:{port}", runs, lab)
    finally:
        proc.terminate()
        proc.wait(timeout=10)


def shot(page: Any, name: str) -> Path:
    """Keep a screenshot of the page's current state as a test artefact."""
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    path = ARTIFACTS / f"{name}.png"
    page.screenshot(path=str(path), full_page=True)
    print(f"screenshot: {path}")
    return path
