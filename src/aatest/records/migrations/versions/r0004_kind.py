"""``calibrations.kind``: a simulation is stored apart from the calibrations.

Records get ``kind`` = ``calibration`` or ``simulation`` (a run with any simulated rig part).
Records registered before this revision from the digital twin (every rig part of their stored
results the ``sim`` plugin family, see :func:`aatest.engine.simulation.simulated_parts`) were
never calibrations: when the records chain is intact they are re-classified as simulations and
the chain is recomputed (``kind`` is hashed when it is not ``calibration``); a broken chain is
left exactly as it is, so re-hashing never hides an edit — ``records check`` still names it.

Revision ID: 0004
Revises: 0003
"""

from __future__ import annotations

import logging

import sqlalchemy as sa
from alembic import op

revision = "0004"
down_revision = "0003"
branch_labels = None
depends_on = None

log = logging.getLogger("aatest.records")


def upgrade() -> None:
    from aatest.engine.simulation import is_simulation
    from aatest.records.chain import check, lock, rehash_all

    with op.batch_alter_table("calibrations") as batch:
        batch.add_column(sa.Column("kind", sa.String(16), nullable=False,
                                   server_default="calibration"))
    bind = op.get_bind()
    lock(bind)
    table = sa.table("calibrations", sa.column("id", sa.Integer),
                     sa.column("results", sa.JSON), sa.column("kind", sa.String))
    simulated = [row.id for row in bind.execute(sa.select(table.c.id, table.c.results))
                 if isinstance(row.results, dict) and is_simulation(row.results)]
    if not simulated:
        return
    if check(bind).broken is not None:
        log.warning("records chain broken: %d digital-twin record(s) left as calibrations "
                    "(run `aatest records check`)", len(simulated))
        return
    bind.execute(table.update().where(table.c.id.in_(simulated)).values(kind="simulation"))
    rehash_all(bind)


def downgrade() -> None:
    with op.batch_alter_table("calibrations") as batch:
        batch.drop_column("kind")
