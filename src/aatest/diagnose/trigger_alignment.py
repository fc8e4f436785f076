"""Alignment without sync edges: the trigger marks the table's first sample on the DAQ clock.

When a step's freeze-pulse edges are missing or inconsistent, diagnose still replays it: the
DAQ record is placed on the table's time grid from the trigger alone, assuming one clock. The
DAQ clock drift is then not measured by edges but fitted from the phase trend of the sine
steps (docs/interfaces.md §4 ``clock_drift``: "found from the sync edges or, without them, from the
phase trend").
"""

from __future__ import annotations

import numpy as np

from aatest.clocksync.freeze_pulse import ClockRelation, SyncedStep
from aatest.clocksync.spline import uniform_cubic_spline
from aatest.recording.dataset import StepData

_DIGITAL = ("sync_pulse", "trigger")
#: a digital trigger line (0/1 volts-as-logged) is high above this level
TRIGGER_THRESHOLD = 0.5


def trigger_aligned(data: StepData) -> SyncedStep | None:
    """The step on the table grid from the trigger edge (drift 0, no edges); None if no trigger."""
    daq, table = data.daq, data.table
    if "trigger" not in daq.channels:
        return None
    high = np.asarray(daq["trigger"]) > TRIGGER_THRESHOLD
    if not high.any():
        return None
    n = daq.time_s.size
    daq_t = float(daq.time_s[0]) + np.arange(n) / daq.sample_rate_hz  # crystal-regular grid
    first = int(np.argmax(high))
    table_t = np.asarray(table.time_s, dtype=float)
    relation = ClockRelation(offset_s=float(table_t[0] - daq_t[first]), drift_ppm=0.0,
                             residual_rms_us=float("nan"), edges_used=0)
    at_daq = relation.to_daq_s(table_t)
    keep = (at_daq >= daq_t[0]) & (at_daq <= daq_t[-1])
    if keep.sum() < 0.5 * keep.size:
        return None
    channels = {}
    # the grid is regular by construction: the not-a-knot spline through it is the uniform
    # B-spline of :mod:`aatest.clocksync.spline` (CubicSpline's values to rounding, 3× faster)
    at_index = (at_daq[keep] - daq_t[0]) * daq.sample_rate_hz
    for name, values in daq.channels.items():
        v = np.asarray(values, dtype=float)
        if name in _DIGITAL:
            idx = np.clip(np.searchsorted(daq_t, at_daq[keep]), 0, n - 1)
            channels[name] = v[idx]
        else:
            channels[name] = uniform_cubic_spline(v, at_index)
    return SyncedStep(step=data.step, time_s=table_t[keep], sample_rate_hz=table.sample_rate_hz,
                      table={k: np.asarray(v)[keep] for k, v in table.channels.items()},
                      daq=channels, relation=relation)
