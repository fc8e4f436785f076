"""Fleet fixtures: no test may read or write the user's own records or lab profile."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(autouse=True)
def _isolated_records(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("AATEST_RECORDS", f"sqlite:///{tmp_path / 'default-records.sqlite'}")
    monkeypatch.delenv("AATEST_LAB", raising=False)
