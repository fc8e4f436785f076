"""Bring a records database to the current schema with the Alembic migrations shipped in-package."""

from __future__ import annotations

from pathlib import Path

from alembic import command
from alembic.config import Config
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory
from sqlalchemy import text
from sqlalchemy.engine import Engine

_MIGRATIONS = Path(__file__).with_name("migrations")
#: advisory-lock key of schema migrations (any constant unique to aatest)
_LOCK_KEY = 0x6161_7465_7374


def _config() -> Config:
    config = Config()
    config.set_main_option("script_location", str(_MIGRATIONS))
    return config


def head_revision() -> str:
    """The schema version this aatest writes."""
    head = ScriptDirectory.from_config(_config()).get_current_head()
    assert head is not None, "the packaged migrations have no head"
    return head


def known_revision(revision: str | None) -> bool:
    """True when ``revision`` is one of the shipped migrations (or ``None``: an empty store);
    a store at an unknown revision was written by a newer aatest."""
    from alembic.util import CommandError

    if revision is None:
        return True
    try:
        return ScriptDirectory.from_config(_config()).get_revision(revision) is not None
    except CommandError:
        return False


def current_revision(engine: Engine) -> str | None:
    """The schema version of the database (``None`` for an empty database)."""
    with engine.connect() as connection:
        return MigrationContext.configure(connection).get_current_revision()


def upgrade(engine: Engine, revision: str = "head") -> None:
    """Apply every migration up to ``revision`` in one transaction (idempotent).

    Stations opening a new store at once are serialised: on PostgreSQL by a transaction-level
    advisory lock, on SQLite by the write lock ``BEGIN IMMEDIATE`` takes; the later one then
    finds the schema current and does nothing.
    """
    config = _config()
    with engine.begin() as connection:
        if connection.dialect.name == "postgresql":
            connection.execute(text("SELECT pg_advisory_xact_lock(:key)"), {"key": _LOCK_KEY})
        config.attributes["connection"] = connection
        command.upgrade(config, revision)
