"""Effects that change the waveform: delay, jerk, dynamics, hysteresis, saturation.

The time family (delay, jerk, dynamics) all shift the phase of a sine; they are fitted with
the logger alignment taken as synchronised (no nuisance offset), and each must beat the
nominal model *with* its ±1-sample alignment nuisance — so a shift the sync pulse cannot
resolve is never evidence (docs/interfaces.md §4). Signatures that tell them apart: a delay lags at
flat magnitude, a jerk term leads, second-order dynamics droop or peak in magnitude and lag
non-linearly in frequency, hysteresis lags more at small amplitude, saturation flattens peaks.
With ``fp_latch_s`` the alignment is resolved and there is no nuisance to beat: a sub-sample
lag or lead is then evidence (:mod:`aatest.diagnose.alignment`).
"""

from __future__ import annotations

import numpy as np
from scipy import optimize

from aatest.diagnose.candidates.base import (
    CandidateFit,
    Context,
    curvature_ci,
    dynamic_peak_dps2,
    linear_ci,
    replace_spec,
    scalar_search,
)
from aatest.diagnose.design import step_columns
from aatest.diagnose.spec import Spec

MAX_DELAY_S = 0.08
#: sine frequencies needed before second-order dynamics can be told from a delay
MIN_FREQUENCIES = 2
#: search bounds of the damping ratio and of the natural frequency (Hz)
DAMPING_BOUNDS = (0.05, 3.0)
MAX_NATURAL_HZ = 1000.0
#: a natural frequency within this share of its upper bound is the bound, not an estimate
BOUND_MARGIN = 0.01
#: a magnitude within this share of 1 at the highest tested frequency is "flat"
FLAT_MAGNITUDE = 0.005
#: a coarse fit must lower the residual by this share before an expensive refinement
REFINE_GAIN = 1e-3
#: cost of a parameter outside its bounds (finite, so simplex arithmetic stays defined)
_OUTSIDE = 1e200
#: delay seeds: geometric, so that 0.5 ms and 50 ms are both bracketed
_DELAY_SEEDS = [0.0, 2.5e-4, 5e-4, 1e-3, 2e-3, 4e-3, 8e-3, 1.6e-2, 3.2e-2, 6.4e-2, MAX_DELAY_S]


def testable_dynamic(ctx: Context) -> str | None:
    return None if ctx.dynamic_steps else "no sine step: nothing excites the sensor dynamically"


def testable_dynamics(ctx: Context) -> str | None:
    freqs = {round(s.inner.frequency_hz or s.outer.frequency_hz, 6)
             for s in ctx.replay.steps if s.dynamic}
    if len(freqs) < MIN_FREQUENCIES:
        return "needs sine steps at two or more frequencies"
    return None


def _synced(ctx: Context) -> Spec:
    """The current spec with the alignment nuisance removed (trust the sync as recorded).

    An accepted ``time_delay`` is not a nuisance: it stays, so a second timing effect (sensor
    dynamics beside a transport delay) is fitted on top of it, not instead of it.
    """
    delay = ctx.current.spec.delay_s if "time_delay" in ctx.accepted else 0.0
    return replace_spec(ctx.current.spec, delay_s=delay, step_shift_s=())


def fit_delay(ctx: Context) -> CandidateFit:
    base = _synced(ctx)

    def make(d: float):
        return replace_spec(base, delay_s=d)

    d, fit = scalar_search(ctx, make, 0.0, MAX_DELAY_S, _DELAY_SEEDS, xtol=1e-7)
    ci = curvature_ci(ctx, make, d, max(1e-6, 0.01 * d), lo=0.0)
    out = CandidateFit("time_delay", fit, {"delay_s": d}, {"delay_s": ci})
    if ctx.within_sync_resolution(d):
        out.veto = (f"lag {d * 1e3:.3f} ms is within the sync's resolution without fp_latch_s: "
                    "it cannot be told from a logger offset")
    return out


def fit_jerk(ctx: Context) -> CandidateFit:
    fit = ctx.fit(_synced(ctx).with_linear("jerk_sensitivity"))
    c, ci = linear_ci(ctx, fit, "jerk_sensitivity", divide_by_scale=False)
    lead_s = c / ctx.scale_of(fit)
    out = CandidateFit("jerk_sensitivity", fit, {"coefficient_v_per_dps3": c},
                       {"coefficient_v_per_dps3": ci}, extra={"equivalent_lead_s": lead_s})
    if lead_s <= 0:
        out.veto = "the term lags the motion: a lag is time_delay's signature, not jerk's"
    elif ctx.within_sync_resolution(lead_s):
        out.veto = (f"lead {lead_s * 1e3:.3f} ms is within the sync's resolution without "
                    "fp_latch_s: it cannot be told from a logger offset")
    return out


def measured_frf(ctx: Context, base: Spec) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(f Hz, H, weight) of every sine step: measured response over the replayed input.

    H is the complex ratio of the output's fundamental to K times the nominal chain's
    fundamental, so it holds only what the nominal model lacks (the sensor's own dynamics).
    """
    fit = ctx.fit(base)
    freqs, ratios, weights = [], [], []
    for sr in ctx.replay.steps:
        f0 = sr.inner.frequency_hz or sr.outer.frequency_hz
        if f0 <= 0.0:
            continue
        cols = step_columns(sr, ctx.info, base, fit.names)
        drive = cols[:, 1]
        others = cols @ fit.coef - fit.coef[1] * drive
        e = np.exp(-2j * np.pi * f0 * sr.time_s)
        a = np.mean((drive - drive.mean()) * e)
        if abs(a) < 1.0:  # under 1 °/s² along the sensitive axis: no dynamic information
            continue
        y = ctx.targets[sr.index] - others
        freqs.append(f0)
        ratios.append(np.mean((y - y.mean()) * e) / (ctx.scale_of(fit) * a))
        weights.append(abs(a))
    return np.asarray(freqs), np.asarray(ratios), np.asarray(weights)


def _second_order(f_hz: np.ndarray, fn: float, zeta: float) -> np.ndarray:
    r = f_hz / fn
    return 1.0 / (1.0 - r * r + 2j * zeta * r)


def _frf_seed(ctx: Context, base: Spec, with_delay: bool = False) -> np.ndarray:
    """(log fn, ζ[, delay s]) fitted to the measured FRF (fast: no time-domain replay).

    ``with_delay``: the FRF is measured without the base's delay and fitted as second-order
    dynamics times a transport delay, so the two lags are separated by their signatures (a
    delay's phase grows linearly with frequency at flat magnitude; dynamics bend both).
    """
    default = np.array([np.log(100.0), 0.7] + ([base.delay_s] if with_delay else []))
    f, h, w = measured_frf(ctx, replace_spec(base, delay_s=0.0) if with_delay else base)
    if f.size < MIN_FREQUENCIES + with_delay:
        return default

    def resid(p: np.ndarray) -> np.ndarray:
        model = _second_order(f, float(np.exp(p[0])), float(p[1]))
        if with_delay:
            model = model * np.exp(-2j * np.pi * f * p[2])
        d = w * (model - h)
        return np.concatenate([d.real, d.imag])

    lo = [0.0, DAMPING_BOUNDS[0]] + ([0.0] if with_delay else [])
    hi = [np.log(MAX_NATURAL_HZ), DAMPING_BOUNDS[1]] + ([MAX_DELAY_S] if with_delay else [])
    best_x, best_cost = default, np.inf
    for fn0 in (5.0, 20.0, 80.0, 300.0):
        for z0 in (0.3, 0.7, 1.2):
            start = [np.log(fn0), z0] + ([0.5 * base.delay_s] if with_delay else [])
            res = optimize.least_squares(resid, start, bounds=(lo, hi))
            if res.cost < best_cost:
                best_x, best_cost = np.asarray(res.x), float(res.cost)
    return best_x


def fit_dynamics(ctx: Context) -> CandidateFit:
    """Second-order low-pass, seeded from the measured FRF, polished on the full replay."""
    base = _synced(ctx)

    def make(p: np.ndarray):
        return replace_spec(base, dynamics=(round(float(np.exp(p[0])), 9), round(float(p[1]), 9)))

    def cost(p: np.ndarray) -> float:
        if not (DAMPING_BOUNDS[0] <= p[1] <= DAMPING_BOUNDS[1]
                and 0.0 <= p[0] <= np.log(MAX_NATURAL_HZ)):
            return _OUTSIDE
        return ctx.fit(make(p)).sse_in

    seed = _frf_seed(ctx, base, with_delay="time_delay" in ctx.accepted)
    if seed.size > MIN_FREQUENCIES:  # the accepted delay re-seeded jointly with the dynamics
        base = replace_spec(base, delay_s=round(float(seed[2]), 12))
    start = seed[:2]
    res = optimize.minimize(cost, start, method="Nelder-Mead",
                            options={"xatol": 1e-4, "fatol": 1e-10 * cost(start), "maxiter": 40,
                                     "initial_simplex": [start, start + np.array([0.02, 0.0]),
                                                         start + np.array([0.0, 0.02])]})
    fn, zeta = float(np.exp(res.x[0])), float(res.x[1])
    fit = ctx.fit(make(res.x))
    ci_fn = curvature_ci(ctx, lambda v: replace_spec(base, dynamics=(v, zeta)), fn, 0.01 * fn,
                         lo=0.5)
    ci_z = curvature_ci(ctx, lambda v: replace_spec(base, dynamics=(fn, v)), zeta, 0.01 * zeta,
                        lo=0.01)
    out = CandidateFit("sensor_dynamics", fit, {"natural_frequency_hz": fn, "damping": zeta},
                       {"natural_frequency_hz": ci_fn, "damping": ci_z},
                       extra={"equivalent_lag_s": 2 * zeta / (2 * np.pi * fn)})
    if fn >= (1.0 - BOUND_MARGIN) * MAX_NATURAL_HZ:
        # the fit ran to the search bound: no resonance inside the sampled band, only a
        # mismatch of the fast parts of the chain (a large ripple's harmonics) it bends to fit
        out.veto = (f"the natural frequency ran to the search bound ({MAX_NATURAL_HZ:g} Hz): "
                    "the data locate no resonance")
    elif ctx.within_sync_resolution(2 * zeta / (2 * np.pi * fn)) and not _droops(fn, zeta, ctx):
        out.veto = ("its lag is within the sync's resolution and its magnitude is flat over "
                    "the tested band")
    return out


def _droops(fn: float, zeta: float, ctx: Context) -> bool:
    """Whether |H| departs by > 0.5 % from 1 at the highest tested frequency."""
    f = max((s.inner.frequency_hz or s.outer.frequency_hz) for s in ctx.replay.steps
            if s.dynamic)
    r = f / fn
    mag = 1.0 / np.hypot(1 - r * r, 2 * zeta * r)
    return abs(mag - 1.0) > FLAT_MAGNITUDE


def fit_hysteresis(ctx: Context) -> CandidateFit:
    """Play operator half width, fitted jointly with the ±1-sample alignment nuisance.

    Hysteresis lags a sine by ≈ r/A rad, comparable to the sync's sub-sample offset at large
    amplitude; the two separate because only hysteresis grows as the amplitude falls. A dead
    band narrower than one step of the stated converter is vetoed (:func:`_below_converter`).
    """
    out = _fit_play(ctx)
    out.veto = _below_converter(ctx, out)
    return out


def _below_converter(ctx: Context, out: CandidateFit) -> str | None:
    """Why a fitted play operator is not evidence of sensor hysteresis, or None.

    A play of half width r moves the reading by at most r·|K| (V), a dead band of 2·r·|K|.
    The logger is stated only down to its converter step q (range and bits); within one step
    its transfer is not characterised — a real converter's code-transition hysteresis and
    differential nonlinearity are of that size — so a dead band 2·r·|K| ≤ q lies where the
    logger's own staircase is unknown and is not attributed to the sensor, even when noise
    dithers it finely enough for the fit to resolve it. A sub-step play that lowers the
    residual may as well be fitting structure of another origin (docs/interfaces.md §4).
    Without a stated logger the stated default (±10 V, 16 bit, q = 305 µV) applies, as in
    the uncertainty budget's resolution row.
    """
    band_v = 2.0 * out.parameters["half_width_dps2"] * abs(ctx.scale_of(out.fit))
    if band_v > ctx.converter_step_v:
        return None
    return (f"dead band 2·r·|K| = {band_v * 1e6:.0f} µV is within one step of the stated "
            f"converter (q = {ctx.converter_step_v * 1e6:.0f} µV): below the logger's resolution")


def _fit_play(ctx: Context) -> CandidateFit:
    """The play operator's half width that best explains the data (no veto)."""
    base = ctx.current.spec
    peak = dynamic_peak_dps2(ctx)
    hi = 0.1 * peak

    def make_on(spec: Spec):
        return lambda r: replace_spec(spec, hysteresis_dps2=r)

    make = make_on(base)
    seeds = [0.0, *list(hi * np.geomspace(0.001, 1.0, 10))]
    r0, coarse = scalar_search(ctx, make, 0.0, hi, seeds)
    if coarse.sse_in > (1.0 - REFINE_GAIN) * ctx.current.sse_in:
        # no trace of a play operator: the joint refinement cannot change the verdict
        ci = curvature_ci(ctx, make, r0, max(0.01 * r0, 1e-4), lo=0.0)
        return CandidateFit("hysteresis", coarse, {"half_width_dps2": r0}, {"half_width_dps2": ci})

    def profiled(r: float):
        """The fit at half width r with every step's alignment re-optimised for it."""
        if ctx.alignment_resolved:
            return ctx.fit(make(r))
        from aatest.diagnose.alignment import refine_step_shifts

        return ctx.fit(refine_step_shifts(ctx, ctx.fit(make(r))))

    res = optimize.minimize_scalar(lambda r: profiled(r).sse_in, bounds=(0.5 * r0, min(3 * r0, hi)),
                                   method="bounded", options={"xatol": 0.005 * r0, "maxiter": 12})
    r, fit = float(res.x), profiled(float(res.x))
    ci = curvature_ci(ctx, lambda v: replace_spec(fit.spec, hysteresis_dps2=v), r,
                      max(0.01 * r, 1e-4), lo=0.0)
    return CandidateFit("hysteresis", fit, {"half_width_dps2": r}, {"half_width_dps2": ci})


def fit_saturation(ctx: Context) -> CandidateFit:
    base = ctx.current.spec
    peak = dynamic_peak_dps2(ctx)

    def make(lim: float):
        return replace_spec(base, saturation_dps2=lim)

    seeds = list(peak * np.linspace(0.3, 1.0, 8))
    lim, fit = scalar_search(ctx, make, 0.3 * peak, peak, seeds)
    ci = curvature_ci(ctx, make, lim, 0.002 * lim, hi=peak)
    out = CandidateFit("saturation", fit, {"limit_dps2": lim}, {"limit_dps2": ci})
    if lim >= 0.995 * peak:
        out.veto = "no clipping below the largest commanded acceleration"
    return out
