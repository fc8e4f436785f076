"""Initial records schema: units, certificate numbering, calibrations and their file hashes.

Revision ID: 0001
Revises:
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0001"
down_revision = None
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "units",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("model", sa.String(64), nullable=False),
        sa.Column("serial", sa.String(64), nullable=False),
        sa.UniqueConstraint("model", "serial", name="uq_units_model_serial"),
    )
    op.create_table(
        "certificate_counters",
        sa.Column("prefix", sa.String(16), primary_key=True),
        sa.Column("year", sa.Integer, primary_key=True),
        sa.Column("last_number", sa.Integer, nullable=False),
    )
    op.create_table(
        "certificates",
        sa.Column("number", sa.String(40), primary_key=True),
        sa.Column("prefix", sa.String(16), nullable=False),
        sa.Column("year", sa.Integer, nullable=False),
        sa.Column("sequence", sa.Integer, nullable=False),
        sa.Column("issued_utc", sa.DateTime(timezone=True), nullable=False),
        sa.UniqueConstraint("prefix", "year", "sequence", name="uq_certificates_sequence"),
    )
    op.create_table(
        "calibrations",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("unit_id", sa.Integer, sa.ForeignKey("units.id"), nullable=False, index=True),
        sa.Column("certificate_number", sa.String(40), sa.ForeignKey("certificates.number"),
                  index=True),
        sa.Column("supersedes_id", sa.Integer, sa.ForeignKey("calibrations.id")),
        sa.Column("command", sa.String(16), nullable=False),
        sa.Column("procedure", sa.String(128), nullable=False),
        sa.Column("procedure_sha256", sa.String(64)),
        sa.Column("rig", sa.JSON, nullable=False),
        sa.Column("plugin_versions", sa.JSON, nullable=False),
        sa.Column("operator", sa.String(128)),
        sa.Column("lab", sa.String(128), nullable=False),
        sa.Column("calibrated_utc", sa.DateTime(timezone=True), nullable=False),
        sa.Column("registered_utc", sa.DateTime(timezone=True), nullable=False),
        sa.Column("overall_verdict", sa.String(24), nullable=False),
        sa.Column("verdicts", sa.JSON, nullable=False),
        sa.Column("results", sa.JSON, nullable=False),
        sa.Column("bundle", sa.Text, nullable=False),
    )
    op.create_table(
        "signed_files",
        sa.Column("calibration_id", sa.Integer, sa.ForeignKey("calibrations.id"),
                  primary_key=True),
        sa.Column("name", sa.String(255), primary_key=True),
        sa.Column("sha256", sa.String(64), nullable=False),
    )


def downgrade() -> None:
    for table in ("signed_files", "calibrations", "certificates", "certificate_counters", "units"):
        op.drop_table(table)
