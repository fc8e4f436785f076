"""The not-a-knot cubic spline through uniformly spaced samples, evaluated fast.

Why: resampling a DAQ channel onto the table's instants (:mod:`aatest.clocksync.freeze_pulse`)
is a cubic spline through a 2^17-sample record; :class:`scipy.interpolate.CubicSpline` solves
its banded system and evaluates a piecewise polynomial at arbitrary knots (≈ 15 ms a channel,
a tenth of the stepped sine's analysis). On uniform knots the same interpolating spline is
the cubic B-spline of :func:`scipy.ndimage.map_coordinates` (a recursive prefilter and four
taps per point, ≈ 4 ms); only the end conditions differ (the B-spline mirrors the record,
CubicSpline's "not-a-knot" does not), and the difference between two interpolating cubic
splines with different end conditions decays as (2 − √3)^k ≈ 0.27^k with the distance k
(samples) from the end. So :func:`uniform_cubic_spline` takes the B-spline more than
:data:`EDGE_SAMPLES` from either end (where the end condition's trace is below 0.27^40 ≈ 1e-23
of the signal) and, near an end, the not-a-knot spline through the first or last
:data:`EDGE_WINDOW` samples (whose own cut end is as far away): CubicSpline's values to
rounding everywhere.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage
from scipy.interpolate import CubicSpline

#: queries closer than this to an end of the record (samples) take the not-a-knot spline of
#: the end window: 0.27^40 ≈ 1e-23, below float64 rounding of any signal
EDGE_SAMPLES = 40
#: samples of the end windows: the window's far (cut) end stays EDGE_SAMPLES from the queries
EDGE_WINDOW = 2 * EDGE_SAMPLES + 4


def uniform_cubic_spline(values: np.ndarray, at_index: np.ndarray) -> np.ndarray:
    """The not-a-knot cubic spline through ``values[k]`` at ``k = 0 … n−1``, at the
    fractional indices ``at_index`` (inside ``[0, n − 1]``; what CubicSpline gives there).

    A record shorter than two end windows is handed to CubicSpline whole.

    Raises
    ------
    ValueError
        When a value is not finite, as CubicSpline does (the B-spline's prefilter would
        spread a NaN over the whole record instead).
    """
    y = np.asarray(values, dtype=np.float64)
    u = np.asarray(at_index, dtype=np.float64)
    n = y.size
    if not np.all(np.isfinite(y)):
        raise ValueError("`y` must contain only finite values.")
    if n < 2 * EDGE_WINDOW:
        return np.asarray(CubicSpline(np.arange(n, dtype=np.float64), y)(u))
    out = ndimage.map_coordinates(y, u[None, :], order=3, mode="mirror", prefilter=True)
    head = u < EDGE_SAMPLES
    if head.any():
        out[head] = _window_spline(y[:EDGE_WINDOW], 0, u[head])
    tail = u > n - 1 - EDGE_SAMPLES
    if tail.any():
        out[tail] = _window_spline(y[n - EDGE_WINDOW:], n - EDGE_WINDOW, u[tail])
    return np.asarray(out)


def _window_spline(window: np.ndarray, first: int, at_index: np.ndarray) -> np.ndarray:
    """The not-a-knot spline through ``window`` (samples ``first …``) at ``at_index``."""
    knots = np.arange(first, first + window.size, dtype=np.float64)
    return np.asarray(CubicSpline(knots, window)(at_index))


def uniform_index(time_s: np.ndarray, at_s: np.ndarray) -> np.ndarray:
    """Fractional sample indices of the instants ``at_s`` on the uniform time base ``time_s``
    (a straight line in the index, :func:`~aatest.clocksync.clock_fit.regular_time`)."""
    t = np.asarray(time_s, dtype=np.float64)
    step = (t[-1] - t[0]) / (t.size - 1)
    return (np.asarray(at_s, dtype=np.float64) - t[0]) / step
