"""The table controller's log of a step: its position, rate and acceleration estimates and the
sync pulse it registers, sampled on the table clock from the trigger on, with the truth behind
them (the real motion of each axis on the same grid).

Kept apart from the DAQ side (:mod:`aatest.twin.synthesis`) because the two logs of a step are
computed on two threads (:mod:`aatest.twin.step_synthesis`): this module draws only from the
generator it is given, in a fixed order that :func:`table_uniforms` counts.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from aatest.engine.logs import TABLE, TABLE_CHANNELS, SampledLog
from aatest.twin.clocks import table_sync
from aatest.twin.drawn_ahead import normal_uniforms
from aatest.twin.grid import Grid
from aatest.twin.step_setup import StepSetup, read_only
from aatest.twin.table import STENCIL_PAD, estimate_quanta, estimates


def table_log_with_truth(setup: StepSetup, rng: np.random.Generator,
               pulse: tuple[np.ndarray, np.ndarray] | None = None,
               ) -> tuple[SampledLog, dict[str, Any]]:
    """The table log and its truth; ``pulse`` (:func:`table_pulse`, drawn last) when the
    caller has drawn it already."""
    step, tm = setup.step, setup.model.table
    dt = 1.0 / step.sample_rate_hz
    grid = Grid(setup.trigger_time_s - STENCIL_PAD * dt, dt, step.samples + 2 * STENCIL_PAD)
    channels: dict[str, np.ndarray] = {}
    truth: dict[str, Any] = {}
    axes = (("inner", setup.inner, tm.inner), ("outer", setup.outer, tm.outer))
    for name, axis, axis_model in axes:
        angle, rate, accel = axis.evaluate(grid)
        encoder = axis_model.encoder_error  # what the encoder reports, not where the table is
        seen = angle + encoder.error_deg(angle) if encoder is not None else angle
        est = estimates(seen, axis_model, dt, tm.estimator, rng)
        channels[f"{name}_position_deg"] = est["position_deg"]
        channels[f"{name}_rate_dps"] = est["rate_dps"]
        channels[f"{name}_accel_dps2"] = est["accel_dps2"]
        channels[f"{name}_feedback_deg"] = est["feedback_deg"]
        inner_slice = slice(STENCIL_PAD, STENCIL_PAD + step.samples)
        truth[f"{name}_angle_deg"] = angle[inner_slice]
        truth[f"{name}_rate_dps"] = rate[inner_slice]
        truth[f"{name}_accel_dps2"] = accel[inner_slice]
    time_s = table_times(setup)
    channels["sync_pulse"], channels["fp_latch_s"] = (
        pulse if pulse is not None else table_pulse(setup, time_s, rng))
    moving = "outer" if step.axis == "outer" else "inner"
    truth.update(time_s=time_s, angle_deg=truth[f"{moving}_angle_deg"],
                 rate_dps=truth[f"{moving}_rate_dps"], accel_dps2=truth[f"{moving}_accel_dps2"])
    # encoder counts: the controller's log channels are integer multiples of these
    quanta = {f"{a}_{c}": (q, 0.0) for a, _, m in axes if m.encoder_resolution_deg > 0.0
              for c, q in estimate_quanta(m, dt, tm.estimator).items()}
    log = SampledLog(TABLE, step.sample_rate_hz, time_s,
                     read_only({c: channels[c] for c in TABLE_CHANNELS}), dict(TABLE_CHANNELS),
                     {"time_s": (dt, 0.0), **quanta})
    return log, truth


def table_log(setup: StepSetup, rng: np.random.Generator) -> SampledLog:
    """The table controller's log of a step alone (e.g. its snapshots during a long record)."""
    return table_log_with_truth(setup, rng)[0]


#: rows of a snapshot log whose pulse edges are generated together (bounded memory)
SNAPSHOT_ROWS_PER_WINDOW = 600


def table_pulse(setup: StepSetup, time_s: np.ndarray,
                 rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Sync pulse as registered by the table, with the latch times (table clock).

    A snapshot log (rows further apart than the pulse period, hours long) is done in windows of
    :data:`SNAPSHOT_ROWS_PER_WINDOW` rows, each with the edges since the row before it, so the
    200 edges per second of a long record are never all in memory at once.
    """
    dt_s = float(time_s[1] - time_s[0]) if time_s.size > 1 else 0.0
    if time_s.size <= SNAPSHOT_ROWS_PER_WINDOW or dt_s * setup.clock.sync_hz <= 1.0:
        return _pulse_rows(setup, time_s, rng)
    levels, latches = [], []
    for first in range(0, time_s.size, SNAPSHOT_ROWS_PER_WINDOW):
        start = max(first - 1, 0)  # the row before: its edges register on row `first`
        level, latch = _pulse_rows(setup, time_s[start:first + SNAPSHOT_ROWS_PER_WINDOW], rng)
        levels.append(level[first - start:])
        latches.append(latch[first - start:])
    return np.concatenate(levels), np.concatenate(latches)


def _pulse_rows(setup: StepSetup, time_s: np.ndarray,
                rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """:func:`table_pulse` of consecutive rows ``time_s`` (table clock, s)."""
    clock, trig = setup.clock, setup.trigger_time_s
    daq_span = (np.array([time_s[0] - 0.05, time_s[-1] + 0.05]) + trig - clock.t0_s) / clock.scale
    edge_daq, rising = clock.edges(float(daq_span[0]), float(daq_span[1]), rng)
    edge_table = clock.lab_time(edge_daq) - trig
    level_before = 0.0 if rising[0] else 1.0
    return table_sync(edge_table, rising, level_before, time_s)


def table_times(setup: StepSetup) -> np.ndarray:
    """Table log time stamps (s from the trigger), as :func:`table_log_with_truth` makes them."""
    return np.arange(setup.step.samples) * (1.0 / setup.step.sample_rate_hz)


def table_uniforms(setup: StepSetup) -> int:
    """Uniforms the table log's estimates draw (:func:`aatest.twin.table.estimates`: the
    estimate noise, then the encoder noise, of each axis with that noise, on the padded grid);
    its pulse, drawn after them, is not counted."""
    m = setup.step.samples + 2 * STENCIL_PAD
    table = setup.model.table
    return sum(normal_uniforms(m) for axis in (table.inner, table.outer)
               for sigma in (axis.estimate_noise_deg, axis.encoder_noise_deg) if sigma > 0.0)
