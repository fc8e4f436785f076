"""Records fixtures: a fresh store per test on SQLite and, where a server is given, PostgreSQL.

PostgreSQL tests use the throwaway cluster ``.ci/postgres`` starts (``AATEST_TEST_POSTGRES_URL``);
each test gets its own database, dropped afterwards.
"""

from __future__ import annotations

import os
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest
from sqlalchemy import create_engine, text
from sqlalchemy.engine import make_url

from aatest.records.url import resolve_url

POSTGRES_ENV = "AATEST_TEST_POSTGRES_URL"


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
    server = os.environ.get(POSTGRES_ENV)
    if not server:
        pytest.skip(f"PostgreSQL records test skipped: {POSTGRES_ENV} is not set "
                    "(.ci/run starts a throwaway cluster with .ci/postgres)")
    name = f"aatest_{uuid.uuid4().hex[:12]}"
    admin = create_engine(resolve_url(server), isolation_level="AUTOCOMMIT")
    with admin.connect() as connection:
        connection.execute(text(f'CREATE DATABASE "{name}"'))
    url = make_url(server).set(database=name)
    try:
        yield url.render_as_string(hide_password=False)
    finally:
        with admin.connect() as connection:
            connection.execute(text(f'DROP DATABASE "{name}" WITH (FORCE)'))
        admin.dispose()


@pytest.fixture(params=["sqlite", "postgres"])
def store_url(request: pytest.FixtureRequest) -> str:
    """The same test on both engines."""
    return str(request.getfixturevalue(f"{request.param}_url"))
