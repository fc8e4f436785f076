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

The B-spline is evaluated here, not by map_coordinates: its general route (any rank, any
order, a boundary test and a type switch per point) spent ≈ 22 ns a point, 2.9 ms of the
3.6 ms a 2^17-sample channel took. :func:`_four_taps` makes the same IEEE operations per point
(scipy's ``get_spline_interpolation_weights`` of order 3 and the sum ``0.0 + c0·w0 + … +
c3·w3`` in that order, no fused multiply-add) as whole-array operations on blocks that stay
in the cache: map_coordinates' values bit for bit (tests/clocksync/test_uniform_spline.py
holds it to that), in ≈ half the time.
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
    out = _bspline(y, u)
    head = u < EDGE_SAMPLES
    if head.any():
        out[head] = _window_spline(y[:EDGE_WINDOW], 0, u[head])
    tail = u > n - 1 - EDGE_SAMPLES
    if tail.any():
        out[tail] = _window_spline(y[n - EDGE_WINDOW:], n - EDGE_WINDOW, u[tail])
    return np.asarray(out)


#: points evaluated at a time: the seven scratch arrays of a block stay in the cache, each
#: below glibc's 128 kB mmap threshold (reused, not faulted in again); measured on 2^17
#: points: 2.5 ms at 2048, 1.5 ms at 8192, 1.4 ms at 16384 (map_coordinates 2.9 ms)
_BLOCK = 8192


def _bspline(values: np.ndarray, at_index: np.ndarray) -> np.ndarray:
    """map_coordinates' mirrored cubic B-spline through ``values`` at ``at_index``, bit for bit.

    The prefilter is map_coordinates' own (:func:`scipy.ndimage.spline_filter`); the points
    more than one sample inside the record are evaluated by :func:`_four_taps`, any other
    (an end interval, NaN) by map_coordinates on the same coefficients.
    """
    coefficients = ndimage.spline_filter(values, 3, output=np.float64, mode="mirror")
    inner = (at_index >= 1.0) & (at_index < values.size - 2.0)
    if inner.all():
        return _four_taps(coefficients, at_index)
    out = ndimage.map_coordinates(coefficients, at_index[None, :], order=3, mode="mirror",
                                  prefilter=False)
    if inner.any():
        out[inner] = _four_taps(coefficients, at_index[inner])
    return np.asarray(out)


def _four_taps(coefficients: np.ndarray, at_index: np.ndarray) -> np.ndarray:
    """The cubic B-spline of ``coefficients`` at ``at_index`` (each in ``[1, n − 2)``: all
    four taps inside), with map_coordinates' operations in its order, a block at a time."""
    out = np.empty(at_index.size)
    size = min(_BLOCK, at_index.size)
    x, z, zz, w, w3, tap = (np.empty(size) for _ in range(6))
    index = np.empty(size, dtype=np.intp)
    for first in range(0, at_index.size, _BLOCK):
        u, o = at_index[first:first + _BLOCK], out[first:first + _BLOCK]
        k = u.size
        xs, zs, zzs, ws, w3s, taps, ks = x[:k], z[:k], zz[:k], w[:k], w3[:k], tap[:k], index[:k]
        np.floor(u, out=xs)
        ks[...] = xs
        ks -= 1  # the first tap
        np.subtract(u, xs, out=xs)  # x: from the knot below
        np.subtract(1.0, xs, out=zs)  # z = 1 − x
        np.multiply(zs, zs, out=zzs)
        np.multiply(zzs, zs, out=ws)
        ws /= 6.0  # w0 = z·z·z/6
        np.subtract(1.0, ws, out=w3s)  # w3 = 1 − w0 − w1 − w2, in that order
        # "clip" clips nothing (every tap is inside): it only skips take's error path
        np.take(coefficients, ks, out=o, mode="clip")
        o *= ws
        o += 0.0  # the sum starts at 0.0 (a −0.0 product becomes +0.0, as there)
        _weight(xs, ws, taps)  # w1 = (x·x·(x − 2)·3 + 4)/6
        _add_tap(coefficients, ks, ws, w3s, taps, o)
        _weight(zs, ws, taps)  # w2: the same of z
        _add_tap(coefficients, ks, ws, w3s, taps, o)
        ks += 1
        np.take(coefficients, ks, out=taps, mode="clip")
        taps *= w3s
        o += taps
    return out


def _weight(y: np.ndarray, out: np.ndarray, scratch: np.ndarray) -> None:
    """``out = (y·y·(y − 2)·3 + 4)/6``, evaluated left to right as scipy does."""
    np.multiply(y, y, out=out)
    np.subtract(y, 2.0, out=scratch)
    out *= scratch
    out *= 3.0
    out += 4.0
    out /= 6.0


def _add_tap(coefficients: np.ndarray, index: np.ndarray, weight: np.ndarray,
             last: np.ndarray, scratch: np.ndarray, out: np.ndarray) -> None:
    """The next tap: ``index`` advanced, ``out += coefficients[index]·weight``, and the
    weight taken off the last tap's ``last``."""
    index += 1
    np.take(coefficients, index, out=scratch, mode="clip")
    scratch *= weight
    out += scratch
    last -= weight


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
