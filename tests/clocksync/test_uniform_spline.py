"""The fast resampling spline is CubicSpline's not-a-knot spline (aatest.clocksync.spline)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage
from scipy.interpolate import CubicSpline

from aatest.clocksync import spline
from aatest.clocksync.spline import EDGE_WINDOW, uniform_cubic_spline, uniform_index

#: both are the same interpolating spline, computed two ways: they differ by rounding only. The
#: B-spline prefilter is a recursion of pole 2 − √3 run both ways (gain ≤ 1/(1 − 0.27)² ≈ 1.9
#: a pass), so its rounding stays within a few ulp of the values' scale; measured ≤ 2 ulp on
#: white noise (the least smooth signal), 64 ulp allowed
_ULPS = 64 * np.finfo(np.float64).eps


@pytest.mark.parametrize("n", [7, 2 * EDGE_WINDOW - 1, 2 * EDGE_WINDOW, 5000])
def test_equals_not_a_knot_spline_everywhere(n: int) -> None:
    rng = np.random.default_rng(26)
    y = rng.normal(size=n) + 3.0 * np.sin(0.01 * np.arange(n))
    # every end interval, just inside each end, and random points (unsorted) in between
    u = np.concatenate([[0.0, n - 1.0, 0.25, n - 1.25, 1e-9, n - 1 - 1e-9],
                        rng.uniform(0.0, n - 1.0, size=3 * n)])
    expected = CubicSpline(np.arange(n, dtype=np.float64), y)(u)
    got = uniform_cubic_spline(y, u)
    assert np.max(np.abs(got - expected)) <= _ULPS * np.max(np.abs(y))


def test_a_drifting_grid_on_a_sine_matches_the_spline_on_time_stamps() -> None:
    """The resampling as the sync uses it: a clock 12 ppm slow, starting 700 samples in."""
    fs_hz, n = 2000.0, 20_000
    time_s = 5.0 + np.arange(n) / fs_hz
    y = np.sin(2 * np.pi * 3.0 * time_s) + 1e-3 * np.random.default_rng(3).normal(size=n)
    at_s = time_s[700] + np.arange(18_000) / fs_hz * (1.0 - 12e-6)
    expected = CubicSpline(time_s, y)(at_s)
    got = uniform_cubic_spline(y, uniform_index(time_s, at_s))
    # the fractional index from time stamps of ≈15 s: rounding of 1e-15 s in 5e-4 s steps
    # moves a point by ~1e-12 samples, the value by ~1e-12·2π·3/2000 of the amplitude
    assert np.max(np.abs(got - expected)) <= 1e-13


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_a_value_that_is_not_finite_is_refused_as_cubic_spline_refuses_it(bad: float) -> None:
    y = np.sin(0.1 * np.arange(1000))
    y[500] = bad
    with pytest.raises(ValueError, match="finite"):
        CubicSpline(np.arange(1000.0), y)
    with pytest.raises(ValueError, match="finite"):
        uniform_cubic_spline(y, np.arange(0.0, 999.0, 0.5))


@pytest.mark.parametrize("points", [1, spline._BLOCK, 2 * spline._BLOCK + 3])
def test_the_b_spline_is_map_coordinates_bit_for_bit(points: int) -> None:
    """The blocked evaluation makes map_coordinates' operations in its order: equal values,
    not merely close ones, whether a point lies inside, in an end interval or is NaN."""
    rng = np.random.default_rng(points)
    n = 3000
    y = np.cumsum(rng.normal(size=n)) + 1e3 * np.sin(0.003 * np.arange(n))
    drifting = 0.37 + np.arange(points) * (1.0 - 12e-6) * (n - 1) / max(points, 1)
    scattered = rng.uniform(0.0, n - 1.0, size=points)
    ends = np.array([0.0, 0.5, 1.0, 1.5, n - 3.0, n - 2.5, n - 2.0, n - 1.5, n - 1.0, np.nan])
    for u in (drifting, scattered, np.concatenate([scattered, ends])):
        expected = ndimage.map_coordinates(y, u[None, :], order=3, mode="mirror")
        np.testing.assert_array_equal(spline._bspline(y, u), expected)
