"""Fixtures of the report tests: contract-shaped results as the engine decided them, a run dir."""

from __future__ import annotations

from pathlib import Path

import pytest
from contract_results import decided, make_results

from aatest.results import RunResults


@pytest.fixture
def results() -> RunResults:
    """Fresh typed results with budgets and verdicts (tests may change their copy)."""
    return decided(make_results())


@pytest.fixture
def run_dir(tmp_path: Path) -> Path:
    """A run directory with a small stand-in recording (only its hash matters to reports)."""
    path = tmp_path / "run"
    path.mkdir()
    (path / "recording.mcap").write_bytes(b"\x89MCAP0\r\n" + bytes(range(200)))
    return path
