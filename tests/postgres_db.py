"""A throwaway PostgreSQL database per test, on the cluster ``.ci/run`` starts.

One helper for every suite that runs its records tests on PostgreSQL too (records, fleet,
batch): a new database on the cluster named by :data:`POSTGRES_ENV`, dropped afterwards; the
test is skipped, saying why, when no cluster is configured.
"""

from __future__ import annotations

import os
import uuid
from collections.abc import Iterator
from contextlib import contextmanager

import pytest
from sqlalchemy import create_engine, text
from sqlalchemy.engine import make_url

from aatest.records.url import resolve_url

#: the server URL of the test cluster (``eval "$(.ci/postgres start)"`` sets it)
POSTGRES_ENV = "AATEST_TEST_POSTGRES_URL"


@contextmanager
def throwaway_database(suite: str) -> Iterator[str]:
    """The URL of a new, empty database (password kept: the test must connect); skips the
    ``suite``'s test without a cluster."""
    server = os.environ.get(POSTGRES_ENV)
    if not server:
        pytest.skip(f"PostgreSQL {suite} test skipped: {POSTGRES_ENV} is not set "
                    "(.ci/run starts a throwaway cluster with .ci/postgres)")
    name = f"aatest_{uuid.uuid4().hex[:12]}"
    admin = create_engine(resolve_url(server), isolation_level="AUTOCOMMIT")
    with admin.connect() as connection:
        connection.execute(text(f'CREATE DATABASE "{name}"'))
    try:
        yield make_url(server).set(database=name).render_as_string(hide_password=False)
    finally:
        with admin.connect() as connection:
            connection.execute(text(f'DROP DATABASE "{name}" WITH (FORCE)'))
        admin.dispose()
