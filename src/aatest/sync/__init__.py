"""Synchronisation of the table and sensor loggers (docs/method.md §2).

:func:`synced_steps` is what every analysis calls first: it synchronises each recorded step
once per analysis pass and caches the result in the shared :class:`AnalysisContext`.
"""

from aatest.sync.freeze_pulse import (
    ClockRelation,
    SyncedStep,
    fit_clock_relation,
    synced_steps,
    synchronise,
)

__all__ = ["ClockRelation", "SyncedStep", "fit_clock_relation", "synced_steps", "synchronise"]
