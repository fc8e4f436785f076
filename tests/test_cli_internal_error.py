"""An internal error (a defect, not a user or rig problem) exits 4 with one line and a crash
report — in the run directory when the command has one, else in the user's cache (issue 14)."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from aatest.cli import app
from aatest.engine.errors import EXIT_INTERNAL
from aatest.engine.run import session


def _explode(*_args: object, **_kwargs: object) -> None:
    raise ZeroDivisionError("float division\nby zero")


@pytest.fixture
def broken(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Path:
    monkeypatch.setattr(session, "prepare", _explode)
    # a valid procedure: the preflight reads it before the plan is prepared (and explodes)
    (tmp_path / "p.yaml").write_text("procedure: p\nsensor: {model: sr207}\nsteps: [static: {}]\n")
    cache = tmp_path / "cache"
    monkeypatch.setenv("XDG_CACHE_HOME", str(cache))
    return cache


def _crash_line(output: str) -> tuple[str, Path]:
    lines = output.splitlines()
    assert len(lines) == 1, output
    line = lines[0]
    assert line.startswith("internal error: ZeroDivisionError: float division by zero "
                           "(crash report: "), line
    return line, Path(line.split("crash report: ")[1].split(";")[0])


def test_internal_error_exits_4_with_a_crash_report_in_the_cache(broken: Path,
                                                                 tmp_path: Path) -> None:
    result = CliRunner().invoke(app, ["validate", str(tmp_path / "p.yaml")])
    assert result.exit_code == EXIT_INTERNAL
    _line, report = _crash_line(result.output)
    assert report.parent == broken / "aatest" / "crash"
    text = report.read_text()
    assert "Traceback" in text and "ZeroDivisionError" in text and "_explode" in text
    assert "command line:" in text and "numpy " in text and "aatest crash report, 20" in text


def test_crash_report_goes_into_the_run_directory(broken: Path, tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    result = CliRunner().invoke(app, ["run", str(tmp_path / "p.yaml"), "--out", str(run_dir)])
    assert result.exit_code == EXIT_INTERNAL
    _line, report = _crash_line(result.output)
    assert report.parent == run_dir and report.name.startswith("crash-")
    assert not broken.exists()
