"""``records show`` with a key no database integer can hold is "no such record" (exit 2)."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from aatest.cli import app
from aatest.records.store import RecordStore


@pytest.mark.parametrize("key", ["99999999999999999999999", str(2**63), "²", "١٢"])
def test_show_unknown_huge_or_odd_key_exits_2(tmp_path: Path, key: str) -> None:
    url = f"sqlite:///{tmp_path / 'records.sqlite'}"
    RecordStore.open(url)  # an existing, empty store
    result = CliRunner().invoke(app, ["records", "show", key, "--records", url])
    assert result.exit_code == 2, result.output
    assert f"no record {key!r}" in result.output
