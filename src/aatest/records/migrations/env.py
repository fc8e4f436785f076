"""Alembic environment of the records store: always run on a connection aatest hands over."""

from __future__ import annotations

from alembic import context

from aatest.records.tables import metadata

connection = context.config.attributes["connection"]
context.configure(connection=connection, target_metadata=metadata, render_as_batch=True)
with context.begin_transaction():
    context.run_migrations()
