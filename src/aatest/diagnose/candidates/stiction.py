"""``rotor_stiction``: the rotor sticks to the case around every rate reversal.

While the case's rate about the sensor axis is within ±``breakaway_rate_dps`` of zero the
sensor loses the share ``depth`` of its response (docs/interfaces.md §4). On a sine that gap
sits at the acceleration peaks (the rate is zero there), so its signature is a gain loss *in
phase* with the motion that grows with f/A (the gap's share of the cycle): no fixed dynamics,
delay or jerk term has it (they lag or lead), hysteresis lags, clipping flattens the peaks of
large motions only.

For a given break-away rate the lost response is one design column (the sensed acceleration
inside the gap, through the dynamics) whose coefficient is −depth·K, so only the break-away
rate is searched; ``depth`` comes out of the linear solve.
"""

from __future__ import annotations

import numpy as np

from aatest.diagnose.candidates.base import (
    CandidateFit,
    Context,
    curvature_ci,
    linear_ci,
    replace_spec,
    scalar_search,
)
from aatest.diagnose.replay import sensor_rate
from aatest.diagnose.spec import Spec

#: the gap is searched up to this share of the largest peak rate of a sine step
MAX_SHARE_OF_PEAK_RATE = 0.5
#: geometric seeds of the search, as shares of its upper bound
_SEED_SHARES = np.geomspace(1e-3, 1.0, 13)


def _peak_rates_dps(ctx: Context) -> list[float]:
    """Peak commanded |rate| (°/s) about the sensor axis of every sine step."""
    return [float(np.max(np.abs(sensor_rate(s, ctx.info.axis, s.time_s))))
            for s in ctx.replay.steps if s.dynamic and (s.inner.frequency_hz
                                                        or s.outer.frequency_hz)]


def testable_stiction(ctx: Context) -> str | None:
    rates = _peak_rates_dps(ctx)
    if not rates or max(rates) <= 0.0:
        return "no sine step turns the sensor about its axis: no rate reversal to stick at"
    return None


def fit_stiction(ctx: Context) -> CandidateFit:
    """Break-away rate (searched) and depth (−coefficient/K) of the stiction gap."""
    base = ctx.current.spec
    hi = MAX_SHARE_OF_PEAK_RATE * max(_peak_rates_dps(ctx))

    def make(rate_dps: float) -> Spec:
        return replace_spec(base.with_linear("rotor_stiction"), stiction_dps=rate_dps)

    rate, fit = scalar_search(ctx, make, 0.0, hi, list(hi * _SEED_SHARES))
    value, ci = linear_ci(ctx, fit, "rotor_stiction")
    depth, depth_ci = -value, sorted(-v for v in ci)
    rate_ci = curvature_ci(ctx, make, rate, 0.01 * rate, lo=0.0, hi=hi)
    out = CandidateFit("rotor_stiction", fit, {"breakaway_rate_dps": rate, "depth": depth},
                       {"breakaway_rate_dps": rate_ci, "depth": depth_ci})
    if not 0.0 < depth <= 1.0:
        out.veto = (f"depth {depth:.3g} is outside (0, 1]: the response does not fall "
                    "around the rate reversals")
    return out
