"""Effects that change the waveform: delay, jerk, dynamics, hysteresis, saturation.

The time family (delay, jerk, dynamics) all shift the phase of a sine; they are fitted with
the logger alignment taken as synchronised (no nuisance offset), and each must beat the
nominal model *with* its ±1-sample alignment nuisance — so a shift the sync pulse cannot
resolve is never evidence (contracts.md §4). Signatures that tell them apart: a delay lags at
flat magnitude, a jerk term leads, second-order dynamics droop or peak in magnitude and lag
non-linearly in frequency, hysteresis lags more at small amplitude, saturation flattens peaks.
"""

from __future__ import annotations

import numpy as np
from scipy import optimize

from aatest.plugins.diagnose.effects.base import (
    CandidateFit,
    Context,
    curvature_ci,
    dynamic_peak_dps2,
    linear_ci,
    replace_spec,
    scalar_search,
)

MAX_DELAY_S = 0.08
#: delay seeds: geometric, so that 0.5 ms and 50 ms are both bracketed
_DELAY_SEEDS = [0.0, 2.5e-4, 5e-4, 1e-3, 2e-3, 4e-3, 8e-3, 1.6e-2, 3.2e-2, 6.4e-2, MAX_DELAY_S]


def testable_dynamic(ctx: Context) -> str | None:
    return None if ctx.dynamic_steps else "no sine step: nothing excites the sensor dynamically"


def testable_dynamics(ctx: Context) -> str | None:
    freqs = {round(s.inner.frequency_hz or s.outer.frequency_hz, 6)
             for s in ctx.replay.steps if s.dynamic}
    if len(freqs) < 2:
        return "needs sine steps at two or more frequencies"
    return None


def _synced(ctx: Context):
    """The current spec with the alignment nuisance removed (trust the sync as recorded)."""
    return replace_spec(ctx.current.spec, delay_s=0.0)


def fit_delay(ctx: Context) -> CandidateFit:
    base = _synced(ctx)

    def make(d: float):
        return replace_spec(base, delay_s=d)

    d, fit = scalar_search(ctx, make, 0.0, MAX_DELAY_S, _DELAY_SEEDS, xtol=1e-7)
    ci = curvature_ci(ctx, make, d, max(1e-6, 0.01 * d), lo=0.0)
    out = CandidateFit("time_delay", fit, {"delay_s": d}, {"delay_s": ci})
    if d <= ctx.replay.dt_s:
        out.veto = (f"lag {d * 1e3:.3f} ms is within one sample: the sync pulse cannot tell it "
                    "from a logger offset")
    return out


def fit_jerk(ctx: Context) -> CandidateFit:
    fit = ctx.fit(_synced(ctx).with_linear("jerk_sensitivity"))
    c, ci = linear_ci(ctx, fit, "jerk_sensitivity", divide_by_scale=False)
    lead_s = c / fit.scale
    out = CandidateFit("jerk_sensitivity", fit, {"coefficient_v_per_dps3": c},
                       {"coefficient_v_per_dps3": ci}, extra={"equivalent_lead_s": lead_s})
    if lead_s <= 0:
        out.veto = "the term lags the motion: a lag is time_delay's signature, not jerk's"
    elif lead_s <= ctx.replay.dt_s:
        out.veto = (f"lead {lead_s * 1e3:.3f} ms is within one sample: the sync pulse cannot tell "
                    "it from a logger offset")
    return out


def fit_dynamics(ctx: Context, delay_hint_s: float = 0.0) -> CandidateFit:
    """Second-order low-pass, seeded from the fitted lag τ ≈ 2ζ/ωn."""
    base = _synced(ctx)

    def make(p: np.ndarray):
        return replace_spec(base, dynamics=(float(np.exp(p[0])), float(p[1])))

    def cost(p: np.ndarray) -> float:
        if not (0.05 <= p[1] <= 3.0 and np.log(1.0) <= p[0] <= np.log(1000.0)):
            return np.inf
        return ctx.fit(make(p)).sse_in

    lag = max(delay_hint_s, 2 * ctx.replay.dt_s)
    seeds = [np.array([np.log(min(2 * z / (2 * np.pi * lag), 900.0)), z])
             for z in (0.3, 0.5, 0.7, 1.0, 1.5)]
    start = min(seeds, key=cost)
    res = optimize.minimize(cost, start, method="Nelder-Mead",
                            options={"xatol": 1e-4, "fatol": 1e-9 * cost(start), "maxiter": 120})
    fn, zeta = float(np.exp(res.x[0])), float(res.x[1])
    fit = ctx.fit(make(res.x))
    ci_fn = curvature_ci(ctx, lambda v: replace_spec(base, dynamics=(v, zeta)), fn, 0.01 * fn, lo=0.5)
    ci_z = curvature_ci(ctx, lambda v: replace_spec(base, dynamics=(fn, v)), zeta, 0.01 * zeta, lo=0.01)
    out = CandidateFit("sensor_dynamics", fit, {"natural_frequency_hz": fn, "damping": zeta},
                       {"natural_frequency_hz": ci_fn, "damping": ci_z},
                       extra={"equivalent_lag_s": 2 * zeta / (2 * np.pi * fn)})
    if 2 * zeta / (2 * np.pi * fn) <= ctx.replay.dt_s and not _droops(fn, zeta, ctx):
        out.veto = "its lag is within one sample and its magnitude is flat over the tested band"
    return out


def _droops(fn: float, zeta: float, ctx: Context) -> bool:
    """Whether |H| departs by > 0.5 % from 1 at the highest tested frequency."""
    f = max((s.inner.frequency_hz or s.outer.frequency_hz) for s in ctx.replay.steps
            if s.dynamic)
    r = f / fn
    mag = 1.0 / np.hypot(1 - r * r, 2 * zeta * r)
    return abs(mag - 1.0) > 0.005


def fit_hysteresis(ctx: Context) -> CandidateFit:
    base = ctx.current.spec
    peak = dynamic_peak_dps2(ctx)

    def make(r: float):
        return replace_spec(base, hysteresis_dps2=r)

    hi = 0.1 * peak
    seeds = [0.0] + list(hi * np.geomspace(1e-3, 1.0, 10))
    r, fit = scalar_search(ctx, make, 0.0, hi, seeds)
    ci = curvature_ci(ctx, make, r, max(0.01 * r, 1e-4), lo=0.0)
    return CandidateFit("hysteresis", fit, {"half_width_dps2": r}, {"half_width_dps2": ci})


def fit_saturation(ctx: Context) -> CandidateFit:
    base = ctx.current.spec
    peak = dynamic_peak_dps2(ctx)

    def make(lim: float):
        return replace_spec(base, saturation_dps2=lim)

    seeds = list(peak * np.linspace(0.3, 1.0, 15))
    lim, fit = scalar_search(ctx, make, 0.3 * peak, peak, seeds)
    ci = curvature_ci(ctx, make, lim, 0.002 * lim, hi=peak)
    out = CandidateFit("saturation", fit, {"limit_dps2": lim}, {"limit_dps2": ci})
    if lim >= 0.995 * peak:
        out.veto = "no clipping below the largest commanded acceleration"
    return out
