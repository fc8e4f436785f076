"""The least and the largest value of each sensor channel of a step, and how many samples hold it.

Why the recording keeps these: a logger whose input range is too small for the sensor clips its
output, and a clipped record gives every analysis a wrong answer without any error — the peaks of
a sine are flat and the fitted scale factor is low. Clipping shows as many samples at exactly
the converter's extreme code; a signal that merely peaks near the rail reaches its extreme in a
sample or two. The writer sees every sample once, so it notes per sensor channel (``v_*``) the
extremes and their multiplicities in the step record (``daq_extremes``); the verdict stage judges
them against the stated converter's rails (:mod:`aatest.metrology.logger_rails`) without
decoding the record again. NaN samples (a dropped reading) are left out.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from aatest.engine.logs import SampledLog

#: channel name prefix of the sensor voltages (docs/interfaces.md §2)
SENSOR_PREFIX = "v_"

#: one channel's ``[least, samples at it, largest, samples at it]`` (values in the channel's
#: unit; NaN and 0 samples for a channel without a finite value)
Extremes = list[float]


def of_values(values: np.ndarray) -> Extremes:
    """``[least, samples at it, largest, samples at it]`` of one channel's finite values."""
    exact = np.asarray(values, dtype=np.float64)
    if not exact.size:
        return [float("nan"), 0, float("nan"), 0]
    low, high = float(np.fmin.reduce(exact)), float(np.fmax.reduce(exact))
    return [low, int(np.count_nonzero(exact == low)), high, int(np.count_nonzero(exact == high))]


def merged(first: Extremes, second: Extremes) -> Extremes:
    """The extremes of two parts of one record (a NaN extreme is a part without values)."""
    def side(a: float, n_a: float, b: float, n_b: float, lower: bool) -> tuple[float, float]:
        if a == b:
            return a, n_a + n_b
        if np.isnan(b) or (not np.isnan(a) and (a < b) == lower):
            return a, n_a
        return b, n_b

    low = side(first[0], first[1], second[0], second[1], lower=True)
    high = side(first[2], first[3], second[2], second[3], lower=False)
    return [low[0], int(low[1]), high[0], int(high[1])]


def of_log(log: SampledLog) -> dict[str, Extremes]:
    """The extremes of every floating-point sensor channel (``v_*``) of a log."""
    return {name: of_values(values) for name, values in log.channels.items()
            if name.startswith(SENSOR_PREFIX) and np.asarray(values).dtype.kind == "f"}


def merged_logs(first: Mapping[str, Extremes], second: Mapping[str, Extremes]
                ) -> dict[str, Extremes]:
    """The extremes of a log received in two parts (channels of either part)."""
    return {name: merged(first[name], second[name]) if name in first and name in second
            else list(first.get(name) or second[name]) for name in {**first, **second}}
