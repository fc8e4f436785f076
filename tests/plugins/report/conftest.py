"""Fixtures of the report tests: contract-shaped results as the engine decided them, a run dir."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest
from contract_results import decided, make_results


@pytest.fixture
def results() -> dict[str, Any]:
    """Fresh contract-shaped results with budgets and verdicts (tests may mutate their copy)."""
    return decided(copy.deepcopy(make_results()))


@pytest.fixture
def run_dir(tmp_path: Path) -> Path:
    """A run directory with a small stand-in recording (only its hash matters to reports)."""
    path = tmp_path / "run"
    path.mkdir()
    (path / "recording.mcap").write_bytes(b"\x89MCAP0\r\n" + bytes(range(200)))
    return path
