"""Synchronisation of the table and sensor loggers (docs/method.md §2): a pure library.

Functions take recorded data and return synchronised steps; they keep no state. The ``sync``
analysis plugin calls :func:`synchronise_all` once per analysis pass and hands the steps to
the analyses that require it.
"""

from aatest.sync.edges import joint_slope_range
from aatest.sync.freeze_pulse import (
    ClockRelation,
    SyncedStep,
    fit_clock_relation,
    fit_unlatched_relation,
    synchronise,
    synchronise_all,
)

__all__ = ["ClockRelation", "SyncedStep", "fit_clock_relation", "fit_unlatched_relation",
           "joint_slope_range", "synchronise", "synchronise_all"]
