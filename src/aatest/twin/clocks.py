"""Logger clocks and the freeze-pulse synchronisation signals (docs/method.md §2, §4 of
docs/interfaces.md).

The table controller's clock is the lab reference. The DAQ runs on its own crystal:
DAQ sample j is taken at lab time t0 + (j/fs)·(1 + drift_ppm·1e-6), so a positive drift means a
DAQ second lasts longer than a table second, exactly the contract's
t_table = t0 + t_daq·(1 + drift_ppm·1e-6). The DAQ generates the 100 Hz sync pulse and the trigger;
the table latches each pulse edge at once but registers it one logging cycle late and logs the
latch time ``fp_latch_s`` so the true edge time can be recovered.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aatest.twin.fastmath import standard_normal

#: resolution of the DAQ's time stamps: a 10 MHz counter (far below the µs jitter)
TIMESTAMP_TICK_S = 1e-7
#: the sync pulse is high for this fraction of each period (a square wave)
HIGH_FRACTION = 0.5


@dataclass(frozen=True)
class DaqClock:
    """The DAQ crystal clock of one logging run.

    Parameters
    ----------
    t0_s
        Lab (table-clock) time of DAQ sample 0.
    sample_rate_hz
        Nominal DAQ sample rate (on its own clock).
    drift_ppm
        Rate error; positive = DAQ slower.
    jitter_s
        RMS jitter of the logged DAQ time stamps.
    sync_hz
        Sync pulse frequency on the DAQ clock.
    sync_phase
        Rising edges at DAQ times (m + sync_phase)/sync_hz, 0 < sync_phase < 1.
    edge_jitter_s
        RMS jitter of the physical pulse edges (DAQ seconds) around their nominal times.
    """

    t0_s: float
    sample_rate_hz: float
    drift_ppm: float = 0.0
    jitter_s: float = 0.0
    sync_hz: float = 100.0
    sync_phase: float = 0.25
    edge_jitter_s: float = 0.0

    @property
    def scale(self) -> float:
        """Lab seconds per DAQ second."""
        return 1.0 + self.drift_ppm * 1e-6

    @property
    def lab_dt_s(self) -> float:
        """Spacing of DAQ samples in lab seconds."""
        return self.scale / self.sample_rate_hz

    def lab_time(self, daq_time_s: np.ndarray | float) -> np.ndarray:
        """Lab time of DAQ clock readings."""
        return self.t0_s + np.asarray(daq_time_s) * self.scale

    def daq_times(self, n: int) -> np.ndarray:
        """Nominal DAQ clock time of samples 0..n−1."""
        return np.arange(n) / self.sample_rate_hz

    def stamped(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """Logged time stamps: nominal DAQ times plus white jitter, read from the logger's
        time-stamp counter (ticks of :data:`TIMESTAMP_TICK_S` s) when jittered."""
        t = self.daq_times(n)
        if not self.jitter_s:
            return t
        return np.round((t + self.jitter_s * standard_normal(rng, n)) / TIMESTAMP_TICK_S) \
            * TIMESTAMP_TICK_S

    def sync_level(self, daq_time_s: np.ndarray) -> np.ndarray:
        """Sync pulse level (0/1) at DAQ clock times: high for the first half period."""
        cycles = daq_time_s * self.sync_hz - self.sync_phase
        frac = cycles - np.floor(cycles)
        return (frac < HIGH_FRACTION).astype(np.float64)

    def edges(self, daq_start_s: float, daq_stop_s: float,
              rng: np.random.Generator | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(DAQ times, rising flags) of the physical pulse edges in [start, stop).

        With ``rng`` each edge carries the generator's timing jitter; the DAQ's own samples
        of the pulse (:meth:`sync_level`) are taken on its clock and do not see it.
        """
        m0 = int(np.floor(daq_start_s * self.sync_hz * 2)) - 2
        m1 = int(np.ceil(daq_stop_s * self.sync_hz * 2)) + 2
        half = np.arange(m0, m1)
        times = (half / 2.0 + self.sync_phase) / self.sync_hz
        keep = (times >= daq_start_s) & (times < daq_stop_s)
        times, rising = times[keep], (half[keep] % 2 == 0)
        if rng is not None and self.edge_jitter_s > 0.0:
            times = times + self.edge_jitter_s * rng.standard_normal(times.size)
        return times, rising


def table_sync(edge_times_s: np.ndarray, rising: np.ndarray, level_before: float,
               table_time_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The table's view of the freeze pulse: (sync_pulse, fp_latch_s) on its log rows.

    An edge at table time e is registered one logging cycle late: on row k_e + 1, where k_e is
    the first row at or after e. ``fp_latch_s`` on a row is the time from the true edge to the
    row that registered the most recent edge (held until the next one); 0 before the first.

    Parameters
    ----------
    edge_times_s
        True edge times on the table clock (sorted).
    rising
        True for rising edges.
    level_before
        Pulse level before the first edge.
    table_time_s
        Uniform table log time stamps.
    """
    dt = table_time_s[1] - table_time_s[0]
    first_row = np.ceil((edge_times_s - table_time_s[0]) / dt - 1e-9).astype(np.int64)
    reg_row = np.maximum(first_row, 0) + 1
    # index of the last edge registered at or before each row (O(n) with a running count)
    inside = reg_row < table_time_s.size
    counts = np.bincount(reg_row[inside], minlength=table_time_s.size)
    idx = np.cumsum(counts) - 1
    after = np.where(rising, 1.0, 0.0)
    registered, last = idx >= 0, np.maximum(idx, 0)  # (each formed once for both channels)
    level = np.where(registered, after[last], level_before)
    reg_time = table_time_s[0] + reg_row * dt
    latch = np.where(registered, (reg_time - edge_times_s)[last], 0.0)
    return level, latch
