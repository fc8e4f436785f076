"""A hash chain over the calibration records, computed for the records already stored.

Each row gets ``previous_hash`` and ``row_hash`` (see :mod:`aatest.records.chain`), so an edit
of a verdict, value or uncertainty directly in the database is found by ``aatest records
check`` and ``aatest verify``. Existing rows are chained in id order as they are now: the chain
vouches for them from this upgrade on.

Revision ID: 0003
Revises: 0002
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0003"
down_revision = "0002"
branch_labels = None
depends_on = None


def upgrade() -> None:
    from aatest.records.chain import lock, rehash_all

    with op.batch_alter_table("calibrations") as batch:
        batch.add_column(sa.Column("previous_hash", sa.String(64)))
        batch.add_column(sa.Column("row_hash", sa.String(64)))
    bind = op.get_bind()
    lock(bind)
    rehash_all(bind, with_kind=False)  # the kind column comes with 0004


def downgrade() -> None:
    with op.batch_alter_table("calibrations") as batch:
        batch.drop_column("row_hash")
        batch.drop_column("previous_hash")
