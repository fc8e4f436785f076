"""Key quantities per record and the signing-key fingerprint, back-filled from stored results.

Schema version 1 kept only the whole results document; trend plots and queries need the key
quantities as rows, and ``verify`` needs the fingerprint the bundle was signed with.

Revision ID: 0002
Revises: 0001
"""

from __future__ import annotations

import math
from typing import Any

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


#: key quantity → (analysis, value key, expanded-uncertainty key, unit), as revision 0002 read
#: them; frozen here: a migration reads the documents the store held then, whatever the
#: current results model says (those documents predate it and need not validate against it)
_SCALARS = {"scale_factor": ("scale_factor", "scale_v_per_dps2", "expanded_uncertainty",
                             "V/(°/s²)"),
            "bias": ("bias", "bias_v", "expanded_uncertainty", "V"),
            "g_sensitivity": ("bias", "g_sensitivity_dps2_per_g", None, "(°/s²)/g")}


def _number(value: Any) -> float | None:
    ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
    return float(value) if ok else None


def _stored_quantities(document: dict[str, Any]) -> list[dict[str, Any]]:
    """The scalar key quantities of one stored results document (revision 0002's reading)."""
    analysis = document.get("analysis") or {}
    found = []
    for name, (block, key, u_key, unit) in _SCALARS.items():
        for channel, row in (analysis.get(block) or {}).items():
            value = _number(row.get(key)) if isinstance(row, dict) else None
            if value is not None:
                found.append({"name": f"{name}.{channel}", "value": value, "unit": unit,
                              "expanded_uncertainty": _number(row.get(u_key)) if u_key else None})
    for channel, points in (analysis.get("frf") or {}).items():
        stated = [(f, g, p) for p in points or [] if isinstance(p, dict)
                  for f, g in [(_number(p.get("frequency_hz")), _number(p.get("gain_db")))]
                  if f and g is not None]
        if stated:  # the point nearest 1 Hz
            _f_hz, gain_db, nearest = min(stated, key=lambda row: abs(math.log(row[0] or 1.0)))
            found.append({"name": f"frf_gain.{channel}", "value": gain_db, "unit": "dB",
                          "expanded_uncertainty":
                          _number(nearest.get("gain_expanded_uncertainty_db"))})
    return found


def _backfill(quantities: sa.Table) -> None:

    bind = op.get_bind()
    calibrations = sa.table("calibrations", sa.column("id", sa.Integer),
                            sa.column("results", sa.JSON),
                            sa.column("key_fingerprint", sa.String))
    for row_id, results in bind.execute(sa.select(calibrations.c.id, calibrations.c.results)):
        signature = (results or {}).get("signature") or {}
        bind.execute(calibrations.update().where(calibrations.c.id == row_id)
                     .values(key_fingerprint=signature.get("fingerprint")))
        rows = [{"calibration_id": row_id, **q} for q in _stored_quantities(results or {})]
        if rows:
            bind.execute(quantities.insert(), rows)


def downgrade() -> None:
    op.drop_table("quantities")
    with op.batch_alter_table("calibrations") as batch:
        batch.drop_column("key_fingerprint")
