"""Records fixtures: a fresh store per test on SQLite and, where a server is given, PostgreSQL.

PostgreSQL tests use the throwaway cluster ``.ci/postgres`` starts (``AATEST_TEST_POSTGRES_URL``);
each test gets its own database, dropped afterwards.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from postgres_db import throwaway_database


@pytest.fixture(autouse=True)
def _isolated_records(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """No test here may read or write the user's own records or lab profile."""
    monkeypatch.setenv("AATEST_RECORDS", f"sqlite:///{tmp_path / 'default-records.sqlite'}")
    monkeypatch.delenv("AATEST_LAB", raising=False)
    monkeypatch.delenv("AATEST_SIGNING_KEY", raising=False)


@pytest.fixture
def sqlite_url(tmp_path: Path) -> str:
    return f"sqlite:///{tmp_path / 'records.sqlite'}"


@pytest.fixture
def postgres_url() -> Iterator[str]:
    """A new, empty PostgreSQL database on the test cluster (skips without a cluster)."""
    with throwaway_database("records") as url:
        yield url


@pytest.fixture(params=["sqlite", "postgres"])
def store_url(request: pytest.FixtureRequest) -> str:
    """The same test on both engines."""
    return str(request.getfixturevalue(f"{request.param}_url"))
