"""End to end on the twin: a registered run is diagnosed from its recording on demand."""

from __future__ import annotations

from pathlib import Path

from typer.testing import CliRunner

from aatest.cli import app

QUICK = Path(__file__).parents[1] / "station" / "data" / "quick-scale-factor.yaml"


def test_a_twin_run_is_diagnosed_from_its_recording(tmp_path: Path) -> None:
    runner = CliRunner()
    url = f"sqlite:///{tmp_path / 'records.sqlite'}"
    done = runner.invoke(app, ["run", str(QUICK), "--out", str(tmp_path / "run"), "--records",
                               url, "--serial", "Q1", "--confirm-prompts", "auto"])
    assert done.exit_code == 0, done.output
    # the twin's run is a simulation: left out unless asked, and the output says why
    left_out = runner.invoke(app, ["fleet", "diagnose", "--records", url, "--html",
                                   str(tmp_path / "none.html")])
    assert left_out.exit_code == 0
    assert "simulations are left out" in left_out.output
    asked = runner.invoke(app, ["fleet", "diagnose", "--records", url, "--run-diagnose",
                                "--include-simulations", "--html", str(tmp_path / "d.html")])
    # one unit on the rig: whatever it shows is undecided, never a rig effect (exit 0)
    assert asked.exit_code == 0, asked.output
    assert "1 units diagnosed" in asked.output
    assert "not diagnosed" not in asked.output
