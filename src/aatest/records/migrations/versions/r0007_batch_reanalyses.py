"""``reanalyses``: results of ``aatest batch`` re-analyses, linked to the original record.

A re-analysis never changes the record (or certificate) it re-evaluates: it is a row of its
own, hash-chained over the ``reanalyses`` table, unique per (subject, method hash) so that a
batch re-run skips what is done.

Revision ID: 0007
Revises: 0006
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0007"
down_revision = "0006"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "reanalyses",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("subject", sa.String(512), nullable=False),
        sa.Column("record_id", sa.Integer, sa.ForeignKey("calibrations.id"), index=True),
        sa.Column("recording", sa.Text, nullable=False),
        sa.Column("mode", sa.String(16), nullable=False),
        sa.Column("method_hash", sa.String(64), nullable=False),
        sa.Column("method", sa.JSON, nullable=False),
        sa.Column("aatest_version", sa.String(64), nullable=False),
        sa.Column("analysed_utc", sa.DateTime(timezone=True), nullable=False),
        sa.Column("overall_verdict", sa.String(24), nullable=False),
        sa.Column("verdicts", sa.JSON, nullable=False),
        sa.Column("quantities", sa.JSON, nullable=False),
        sa.Column("outcome", sa.JSON, nullable=False),
        sa.Column("previous_hash", sa.String(64), nullable=False),
        sa.Column("row_hash", sa.String(64), nullable=False),
        sa.UniqueConstraint("subject", "method_hash", name="uq_reanalyses_subject_method"),
    )


def downgrade() -> None:
    op.drop_table("reanalyses")
