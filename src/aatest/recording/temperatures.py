"""The temperatures a run logged, summarised once when it is analysed (for the certificate).

Every ``temperature*`` channel of every step, DAQ and table, reduced to min, mean and max:
a recording's steps are read block by block and only those channels decoded (the temperature of
a 2 h record is 115 MB, its whole DAQ log five times that), so no step's temperature is kept
once summarised.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator
from typing import Any

import numpy as np

from aatest.recording.dataset import Dataset, LazySteps, NamesStartingWith
from aatest.results.root import LoggedTemperature

#: the channels summarised: every name starting with this
TEMPERATURE_PREFIX = "temperature"


def _temperature_columns(data: Dataset) -> Iterator[np.ndarray]:
    """The finite samples (°C) of every ``temperature*`` channel of every step, a piece at a
    time."""
    wanted = NamesStartingWith(TEMPERATURE_PREFIX)
    steps = data.steps
    for index in range(len(steps)):
        logs: Iterable[Any] = (
            (piece for source in ("daq", "table") for piece in steps.pieces(index, source, wanted))
            if isinstance(steps, LazySteps) else (steps[index].daq, steps[index].table))
        for log in logs:
            for name in log.channels:
                if name in wanted:
                    values = np.asarray(log[name], dtype=np.float64)
                    yield values[np.isfinite(values)]


def logged_temperature(data: Dataset) -> LoggedTemperature:
    """Min/mean/max (°C) of every temperature sample ``data`` holds, and where it was read.

    The mean is over all samples of all channels (an exactly rounded sum, ``math.fsum`` of the
    per-piece sums), so it does not depend on how the record was split into pieces.
    """
    lows: list[float] = []
    highs: list[float] = []
    sums: list[float] = []
    count = 0
    for values in _temperature_columns(data):
        if values.size:
            lows.append(float(values.min()))
            highs.append(float(values.max()))
            sums.append(float(np.sum(values)))
            count += int(values.size)
    source = str(data.source)
    if not count:
        return LoggedTemperature(samples=0, source=source)
    return LoggedTemperature(min_c=min(lows), mean_c=math.fsum(sums) / count, max_c=max(highs),
                             samples=count, source=source)
