"""The temperatures a run logged, summarised once when it is analysed (for the certificate).

Every ``temperature*`` channel of every step, DAQ and table, reduced to min, mean and max.
The analysis pass decodes every recorded step once for all its readers (a
:class:`~aatest.recording.dataset.StepWatch`): :func:`watch` has each step's temperature
channels tallied by that decode, so the summary reads a few numbers per step instead of
decoding every step again (measured: 2.2 s of CPU for the stepped sine's 136 steps, 0.003 s
now). A step that decode did not reach (a long record read piece by piece, a dataset in memory,
a results file built without the pass) is read here, block by block and only those channels
(the temperature of a 2 h record is 115 MB, its whole DAQ log five times that), so no step's
temperature is kept once summarised.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from aatest.engine.logs import SampledLog
from aatest.engine.steps import PlannedStep
from aatest.recording.dataset import Dataset, LazySteps, NamesStartingWith, StepData, StepWatch
from aatest.results.root import LoggedTemperature

#: the channels summarised: every name starting with this
TEMPERATURE_PREFIX = "temperature"
#: the name the per-step tally is watched under (:func:`watch`)
WATCH_NAME = "recording.temperatures"
_WANTED = NamesStartingWith(TEMPERATURE_PREFIX)


@dataclass(frozen=True)
class Tally:
    """Min, max (°C), sum (°C) and count of the finite samples of one channel (or piece)."""

    low_c: float
    high_c: float
    sum_c: float
    samples: int


def _tally(logs: Iterable[SampledLog]) -> tuple[Tally, ...]:
    """One :class:`Tally` per non-empty ``temperature*`` channel of each of ``logs``."""
    found = []
    for log in logs:
        for name in log.channels:
            if name in _WANTED:
                values = np.asarray(log[name], dtype=np.float64)
                values = values[np.isfinite(values)]
                if values.size:
                    found.append(Tally(float(values.min()), float(values.max()),
                                       float(np.sum(values)), int(values.size)))
    return tuple(found)


def _tally_step(step: StepData) -> tuple[Tally, ...]:
    """The tallies of a decoded step (both logs; channels not decoded are simply absent)."""
    return _tally((step.daq, step.table))


def _all_sources(_step: PlannedStep) -> dict[str, NamesStartingWith]:
    return {"daq": _WANTED, "table": _WANTED}


def watch(data: Dataset) -> None:
    """Tally each recorded step's temperatures when an analysis first decodes that step.

    Register before the analysis pass (:func:`aatest.engine.analysis.passes.run_analyses`
    does); :func:`logged_temperature` then reads the tallies. Only a recording's lazy steps
    are watched; the values are those a separate read would give (the same samples; the mean
    adds the same sums in another grouping, within rounding).
    """
    if isinstance(data.steps, LazySteps):
        data.steps.watch(WATCH_NAME, StepWatch(_all_sources, lambda _step: True, _tally_step))


def _read_step(steps: Any, index: int) -> tuple[Tally, ...]:
    """The tallies of step ``index`` read now: a recording's step piece by piece and only its
    temperature channels; a step in memory as it is."""
    if not isinstance(steps, LazySteps):
        return _tally_step(steps[index])
    return _tally(piece for source in ("daq", "table")
                  for piece in steps.pieces(index, source, _WANTED))


def _step_tallies(data: Dataset) -> Iterator[Tally]:
    """The tallies of every step: made by the analysis pass's decode where it did, else now."""
    steps = data.steps
    for index in range(len(steps)):
        if isinstance(steps, LazySteps):
            try:
                found: tuple[Tally, ...] = steps.watched(WATCH_NAME, index)
            except KeyError:
                pass
            else:
                yield from found
                continue
        yield from _read_step(steps, index)


def logged_temperature(data: Dataset) -> LoggedTemperature:
    """Min/mean/max (°C) of every temperature sample ``data`` holds, and where it was read.

    The mean is over all samples of all channels (an exactly rounded sum, ``math.fsum`` of the
    per-channel sums), so it does not depend on how the record was split into pieces beyond
    the rounding of each piece's sum.
    """
    tallies = list(_step_tallies(data))
    count = sum(t.samples for t in tallies)
    source = str(data.source)
    if not count:
        return LoggedTemperature(samples=0, source=source)
    return LoggedTemperature(min_c=min(t.low_c for t in tallies),
                             mean_c=math.fsum(t.sum_c for t in tallies) / count,
                             max_c=max(t.high_c for t in tallies), samples=count, source=source)
