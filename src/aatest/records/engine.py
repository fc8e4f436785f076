"""Connections to the records database, with the locking each engine needs.

SQLite: every transaction starts with ``BEGIN IMMEDIATE`` (the write lock is taken up front,
so two stations never both read the same counter) and waits up to ``BUSY_TIMEOUT_S`` for it.
PostgreSQL: plain transactions; the counter row is locked with ``SELECT … FOR UPDATE``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from sqlalchemy import create_engine, event, text
from sqlalchemy.engine import URL, Engine
from sqlalchemy.exc import DBAPIError, OperationalError

from aatest.records.errors import RecordsUnavailable
from aatest.records.url import redacted

BUSY_TIMEOUT_S = 60.0
CONNECT_TIMEOUT_S = 10


def _sqlite_engine(url: URL) -> Engine:
    if url.database and url.database != ":memory:":
        Path(url.database).parent.mkdir(parents=True, exist_ok=True)
    engine = create_engine(url, connect_args={"timeout": BUSY_TIMEOUT_S})

    @event.listens_for(engine, "connect")
    def _no_implicit_begin(dbapi_connection: Any, _record: Any) -> None:
        dbapi_connection.isolation_level = None  # SQLAlchemy's events emit BEGIN themselves
        dbapi_connection.execute("PRAGMA foreign_keys = ON")

    @event.listens_for(engine, "begin")
    def _begin_immediate(connection: Any) -> None:
        connection.exec_driver_sql("BEGIN IMMEDIATE")

    return engine


def open_engine(url: URL) -> Engine:
    """An engine for ``url``, checked by connecting once.

    Raises
    ------
    RecordsUnavailable
        The database cannot be reached or opened; the message names the URL without password.
    """
    if url.get_backend_name() == "sqlite":
        engine = _sqlite_engine(url)
    else:
        engine = create_engine(url, connect_args={"connect_timeout": CONNECT_TIMEOUT_S})
    try:
        with engine.connect() as connection:
            connection.execute(text("SELECT 1"))
    except (OperationalError, DBAPIError, OSError) as exc:
        engine.dispose()
        cause = getattr(exc, "orig", None) or exc
        raise RecordsUnavailable(
            f"records database {redacted(url)} cannot be reached: {' '.join(str(cause).split())}"
            " (check --records / AATEST_RECORDS)"
        ) from exc
    return engine
