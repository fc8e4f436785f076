"""Fleet fixtures: no test may read or write the user's own records or lab profile."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from postgres_db import throwaway_database


@pytest.fixture(autouse=True)
def _isolated_records(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("AATEST_RECORDS", f"sqlite:///{tmp_path / 'default-records.sqlite'}")
    monkeypatch.delenv("AATEST_LAB", raising=False)




@pytest.fixture
def postgres_url() -> Iterator[str]:
    """A new, empty PostgreSQL database on the test cluster (skips without a cluster)."""
    with throwaway_database("fleet") as url:
        yield url


@pytest.fixture(params=["sqlite", "postgres"])
def store_url(request: pytest.FixtureRequest, tmp_path: Path) -> str:
    """The same test on both engines."""
    if request.param == "sqlite":
        return f"sqlite:///{tmp_path / 'records.sqlite'}"
    return str(request.getfixturevalue("postgres_url"))
