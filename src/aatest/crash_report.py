"""Crash reports: what an internal error (exit 4, docs/interfaces.md §1) leaves behind.

An exception that is not an :class:`~aatest.engine.errors.AatestError` is a defect of aatest.
The CLI prints one line and writes this report — traceback, versions, command line, UTC time —
into the run directory when the command has one, else into the user's cache directory
(``$XDG_CACHE_HOME/aatest/crash``, default ``~/.cache/aatest/crash``), so it can be attached
to a bug report.
"""

from __future__ import annotations

import os
import platform
import sys
import traceback
from datetime import UTC, datetime
from importlib import metadata
from pathlib import Path

#: the distributions whose versions help to reproduce a crash
_VERSIONED = ("aatest", "numpy", "scipy", "pydantic", "pymodbus", "python-can", "mcap", "typer")


def cache_dir() -> Path:
    """Where crash reports go when a command has no run directory (XDG cache convention)."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "aatest" / "crash"


def _versions() -> list[str]:
    lines = [f"python {platform.python_version()} ({platform.platform()})"]
    for dist in _VERSIONED:
        try:
            lines.append(f"{dist} {metadata.version(dist)}")
        except metadata.PackageNotFoundError:
            lines.append(f"{dist} not installed")
    return lines


def write_crash_report(exc: BaseException, run_dir: Path | None) -> Path:
    """Write the report of ``exc`` and return its path.

    Parameters
    ----------
    exc
        The unexpected exception, with its traceback.
    run_dir
        The command's run directory when it exists; else the report goes to :func:`cache_dir`.
    """
    now = datetime.now(UTC)
    folder = run_dir if run_dir is not None and run_dir.is_dir() else cache_dir()
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"crash-{now.strftime('%Y%m%dT%H%M%S%fZ')}-{os.getpid()}.txt"
    text = "\n".join([
        f"aatest crash report, {now.isoformat(timespec='seconds')}",
        f"command line: {' '.join(sys.argv)}",
        f"working directory: {Path.cwd()}",
        "", "versions:", *(f"  {line}" for line in _versions()),
        "", "traceback:",
        "".join(traceback.format_exception(type(exc), exc, exc.__traceback__)),
    ])
    path.write_text(text, encoding="utf-8")
    return path
