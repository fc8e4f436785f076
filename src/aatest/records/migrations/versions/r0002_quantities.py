"""Key quantities per record and the signing-key fingerprint, back-filled from stored results.

Schema version 1 kept only the whole results document; trend plots and queries need the key
quantities as rows, and ``verify`` needs the fingerprint the bundle was signed with.

Revision ID: 0002
Revises: 0001
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0002"
down_revision = "0001"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("calibrations") as batch:
        batch.add_column(sa.Column("key_fingerprint", sa.String(64)))
    quantities = op.create_table(
        "quantities",
        sa.Column("calibration_id", sa.Integer, sa.ForeignKey("calibrations.id"),
                  primary_key=True),
        sa.Column("name", sa.String(64), primary_key=True),
        sa.Column("value", sa.Float, nullable=False),
        sa.Column("expanded_uncertainty", sa.Float),
        sa.Column("unit", sa.String(32), nullable=False),
    )
    _backfill(quantities)


def _backfill(quantities: sa.Table) -> None:
    from aatest.records.extract import key_quantities

    bind = op.get_bind()
    calibrations = sa.table("calibrations", sa.column("id", sa.Integer),
                            sa.column("results", sa.JSON),
                            sa.column("key_fingerprint", sa.String))
    for row_id, results in bind.execute(sa.select(calibrations.c.id, calibrations.c.results)):
        signature = (results or {}).get("signature") or {}
        bind.execute(calibrations.update().where(calibrations.c.id == row_id)
                     .values(key_fingerprint=signature.get("fingerprint")))
        rows = [{"calibration_id": row_id, "name": q.name, "value": q.value,
                 "expanded_uncertainty": q.expanded_uncertainty, "unit": q.unit}
                for q in key_quantities(results or {})]
        if rows:
            bind.execute(quantities.insert(), rows)


def downgrade() -> None:
    op.drop_table("quantities")
    with op.batch_alter_table("calibrations") as batch:
        batch.drop_column("key_fingerprint")
