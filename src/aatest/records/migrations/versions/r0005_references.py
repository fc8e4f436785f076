"""``reference_standards``: the lab's reference instruments and their due dates.

Revision ID: 0005
Revises: 0004
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0005"
down_revision = "0004"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "reference_standards",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("identifier", sa.String(64), nullable=False, unique=True),
        sa.Column("kind", sa.String(32), nullable=False),
        sa.Column("certificate_number", sa.String(64), nullable=False),
        sa.Column("issuing_lab", sa.String(128), nullable=False),
        sa.Column("calibrated_on", sa.Date, nullable=False),
        sa.Column("due_on", sa.Date, nullable=False),
        sa.Column("accuracy", sa.Text, nullable=False),
        sa.Column("added_utc", sa.DateTime(timezone=True), nullable=False),
        sa.Column("retired_utc", sa.DateTime(timezone=True)),
        sa.Column("retired_reason", sa.Text),
    )


def downgrade() -> None:
    op.drop_table("reference_standards")
