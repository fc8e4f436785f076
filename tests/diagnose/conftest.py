"""Run ``aatest diagnose`` as a user would: twin data → import directory → CLI → JSON."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from aatest.cli import app
from aatest.diagnose.scenarios import Hidden, draw_hidden, judge, scenario_dataset, without_latch
from aatest.recording.data.exporter import export_csv


def diagnose_cli(tmp: Path, hidden: list[Hidden], seed: int, samples: int = 2**14,
                 latch: bool = True) -> tuple[int, dict[str, Any]]:
    """Export a scenario as an import directory (without ``fp_latch_s`` unless ``latch``)
    and diagnose it through the CLI."""
    data = tmp / "import"
    dataset = scenario_dataset(hidden, seed, samples)
    export_csv(dataset if latch else without_latch(dataset), data)
    out = tmp / "diagnosis.json"
    result = CliRunner().invoke(app, ["diagnose", str(data), "--json", str(out),
                                      "--model-out", str(tmp / "model.yaml")])
    assert result.exception is None or isinstance(result.exception, SystemExit), result.output
    return result.exit_code, json.loads(out.read_text())


@pytest.fixture
def run_diagnose(tmp_path: Path):
    return lambda hidden, seed, samples=2**14: diagnose_cli(tmp_path, hidden, seed, samples)


@pytest.fixture
def diagnose_cli_fn():
    """The CLI runner itself, for tests that make their own temporary directories."""
    return diagnose_cli


@pytest.fixture
def not_claimed_as(run_diagnose):
    """Hide one look-alike effect alone (``draw_hidden(look_alike, seed)``, ``samples`` per
    step): the diagnosis must judge it right and claim nothing as the effect ``named``."""
    def check(named: str, look_alike: str, seed: int, samples: int) -> None:
        hidden = [draw_hidden(look_alike, seed)]
        _, doc = run_diagnose(hidden, seed=seed, samples=samples)
        assert judge(doc, hidden) == []
        assert not any(f["effect"] == named for f in doc["findings"])
    return check
