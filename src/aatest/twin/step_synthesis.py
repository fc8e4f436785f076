"""One step's table log and DAQ log on two threads, with the numbers a serial synthesis draws.

Why: the record phase synthesises each step while the previous one is written; computed one
piece after another on one thread, a step kept the second core idle much of the time. The
pieces are spread so that the caller's thread carries only the chain the DAQ log cannot
shorten (the inner axis and the table top's motion on the DAQ grid, the sensors, the
channels' noise), and one worker thread does the rest in the order the chain needs it: every
random draw of the step, the outer axis and the temperature, the floor's rocking, the time
stamps, then the whole table log.

Same numbers: a short step's two logs draw from one stream, the table log's draws first
(:meth:`aatest.twin.world.World.result`). The worker draws all of them up front, in that
order, onto tapes (:mod:`aatest.twin.drawn_ahead`: ``random(a + b)`` is ``random(a)`` then
``random(b)``), so what each consumer gets does not depend on which thread computes when; a
consumer that draws other than counted makes the step redo itself serially from the saved
stream states (slower, the same bytes). A long record's DAQ log has a stream of its own and
only runs beside the table log. The worker is joined before :func:`synthesise` returns (no
thread outlives a step, so the analysis may fork afterwards).
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, cast

import numpy as np

from aatest.engine.logs import SampledLog
from aatest.twin.drawn_ahead import DrawsDiffer, UniformTape
from aatest.twin.rigid_motion import outer_part
from aatest.twin.step_setup import LazyTruth, SimulatedStep, StepSetup
from aatest.twin.synthesis import (
    BlockAhead,
    _block_grid,
    _daq_log,
    _daq_samples,
    _stamped,
    floor_rocking_block,
    floor_uniforms,
    generation_block,
    record_uniforms,
    stamp_uniforms,
)
from aatest.twin.table_log import table_log_with_truth, table_pulse, table_times, table_uniforms

_BothLogs = tuple[SampledLog, dict[str, Any], SampledLog, LazyTruth]


def synthesise(setup: StepSetup, rng: np.random.Generator,
               daq_rng: np.random.Generator | None = None,
               drift_rng: np.random.Generator | None = None) -> SimulatedStep:
    """Table log, DAQ log and truth of one step (all vectorised).

    ``daq_rng`` (default: ``rng`` after the table log) draws the DAQ log, ``drift_rng`` the
    sensors' bias drift; a streamed record uses the same two streams
    (:func:`aatest.twin.synthesis.daq_blocks`).
    """
    if daq_rng is not None:
        table, table_truth, daq, truth = _two_streams(setup, rng, daq_rng, drift_rng)
    else:
        table, table_truth, daq, truth = _one_stream(setup, rng, drift_rng)
    truth.update(table_truth)
    truth["drift_ppm"] = setup.clock.drift_ppm
    # t_table_log = offset + t_daq·(1 + drift): the DAQ's sample 0 precedes the trigger
    truth["offset_s"] = setup.clock.t0_s - setup.trigger_time_s
    truth["temperature_c"] = float(setup.thermal.temperature_at(setup.trigger_time_s))
    return SimulatedStep(table=table, daq=daq, truth=truth)


def _two_streams(setup: StepSetup, rng: np.random.Generator, daq_rng: np.random.Generator,
                 drift_rng: np.random.Generator | None) -> _BothLogs:
    """The table log on a worker, the DAQ log (its own streams) on this thread."""
    with ThreadPoolExecutor(max_workers=1, thread_name_prefix="aatest-twin") as pool:
        table = pool.submit(table_log_with_truth, setup, rng)
        daq, truth = _daq_log(setup, daq_rng, drift_rng)
        return *table.result(), daq, truth


def _serial(setup: StepSetup, rng: np.random.Generator,
            drift_rng: np.random.Generator | None) -> _BothLogs:
    """The table log, then the DAQ log, from one stream (the reference order of draws)."""
    table, table_truth = table_log_with_truth(setup, rng)
    return table, table_truth, *_daq_log(setup, rng, drift_rng)


@dataclass(frozen=True)
class _Drawn:
    """Every draw of a one-stream, one-block step, in the stream's order."""

    table: UniformTape
    pulse: tuple[np.ndarray, np.ndarray]
    floor: UniformTape
    record: UniformTape
    stamps: UniformTape

    @property
    def exhausted(self) -> bool:
        return all(t.exhausted for t in (self.table, self.floor, self.record, self.stamps))


def _draw(setup: StepSetup, rng: np.random.Generator) -> _Drawn:
    """Draw the step's numbers in the order a serial synthesis draws them: the table log's
    estimates, its pulse, then the DAQ log's floor rocking, channel noise and time stamps."""
    n, model = _daq_samples(setup), setup.model
    table = UniformTape(rng, table_uniforms(setup))
    pulse = table_pulse(setup, table_times(setup), rng)
    return _Drawn(table, pulse, UniformTape(rng, floor_uniforms(model.table, n)),
                  UniformTape(rng, sum(record_uniforms(s, model.daq, n) for s in model.sensors)),
                  UniformTape(rng, stamp_uniforms(setup.clock, n)))


def _one_stream(setup: StepSetup, rng: np.random.Generator,
                drift_rng: np.random.Generator | None) -> _BothLogs:
    """Both logs from one stream: overlapped, or serially again from the saved stream states
    when a log drew otherwise than counted (same numbers either way)."""
    n = _daq_samples(setup)
    if generation_block(n) < n:  # a long record on one stream (World gives it its own)
        return _serial(setup, rng, drift_rng)
    saved_rng = rng.bit_generator.state
    saved_drift = drift_rng.bit_generator.state if drift_rng is not None else None
    try:
        logs, drawn = _overlapped(setup, rng, drift_rng)
        if drawn.exhausted:
            return logs
    except DrawsDiffer:
        pass
    rng.bit_generator.state = saved_rng
    if drift_rng is not None and saved_drift is not None:
        drift_rng.bit_generator.state = saved_drift
    return _serial(setup, rng, drift_rng)


def _overlapped(setup: StepSetup, rng: np.random.Generator,
                drift_rng: np.random.Generator | None) -> tuple[_BothLogs, _Drawn]:
    """The worker draws everything, then computes what the DAQ chain needs in the order it
    needs it, then the table log; this thread computes the DAQ chain. Only the worker draws
    from ``rng``."""
    n, clock = _daq_samples(setup), setup.clock
    with ThreadPoolExecutor(max_workers=1, thread_name_prefix="aatest-twin") as pool:
        drawn = pool.submit(_draw, setup, rng)
        ahead = BlockAhead(
            outer=pool.submit(outer_part, setup, _block_grid(clock, 0, n)),
            floor=pool.submit(lambda: floor_rocking_block(
                setup.model.table, n, clock.lab_dt_s, _tape(drawn.result().floor), None)),
            stamps=pool.submit(lambda: _stamped(clock, 0, n, _tape(drawn.result().stamps))),
            record=_later(drawn, lambda d: _tape(d.record)))
        table = pool.submit(lambda: table_log_with_truth(
            setup, _tape(drawn.result().table), drawn.result().pulse))
        daq, truth = _daq_log(setup, _tape(_NO_DRAWS), drift_rng, ahead)
        return (*table.result(), daq, truth), drawn.result()


#: the DAQ log's own stream when everything it draws comes through ``ahead``: drawing from it
#: is a miscount (the step is redone serially)
_NO_DRAWS = UniformTape(np.random.default_rng(0), 0)


def _tape(tape: UniformTape) -> np.random.Generator:
    """A tape where a generator is expected (it serves ``random`` alone)."""
    return cast(np.random.Generator, tape)


def _later(drawn: Future[_Drawn],
           pick: Callable[[_Drawn], np.random.Generator]) -> Future[np.random.Generator]:
    """A future of ``pick(drawn)``, done when ``drawn`` is (no thread of its own)."""
    result: Future[np.random.Generator] = Future()

    def done(future: Future[_Drawn]) -> None:
        try:
            result.set_result(pick(future.result()))
        except BaseException as exc:  # noqa: BLE001 - handed on to whoever waits
            result.set_exception(exc)

    drawn.add_done_callback(done)
    return result
