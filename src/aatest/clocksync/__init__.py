"""Clock synchronisation of the table and sensor loggers (docs/method.md §2): a pure library.

Functions take recorded data and return synchronised steps; they keep no state. The ``sync``
analysis plugin (:mod:`aatest.plugins.analysis.sync`, result :mod:`aatest.results.sync`) calls
:func:`synchronise_all` once per analysis pass and hands the steps to the analyses that require
it. "sync" names that analysis only; this package is *clocksync*, and diagnose's alignment of a
step without freeze-pulse edges is :mod:`aatest.diagnose.trigger_alignment`.

- ``freeze_pulse``  the clock relation of one step from its freeze-pulse edges, synchronised steps
- ``edges``         freeze-pulse edges paired by time; the clock relation without latch times
- ``streamed``      a long record the table logged the head of, read block by block
- ``phase_trend``   without latch times, the drift the sine steps' sensor phase trend fixes
                    where the edges only bound it
"""

from aatest.clocksync.edges import joint_slope_range
from aatest.clocksync.freeze_pulse import (
    ClockRelation,
    SyncedStep,
    fit_clock_relation,
    fit_unlatched_relation,
    synchronise,
    synchronise_all,
)

__all__ = ["ClockRelation", "SyncedStep", "fit_clock_relation", "fit_unlatched_relation",
           "joint_slope_range", "synchronise", "synchronise_all"]
