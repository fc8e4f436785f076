"""Logger alignment in the nominal model: what the sync pulse resolves, and what it does not.

Without ``fp_latch_s`` the table registers an edge at its next sample, so the pulse aligns the
loggers to about one sample: the edge estimate itself is uncertain by ±½ sample, and on top of
it an offset smaller than one sample is not evidence of ``time_delay`` (docs/interfaces.md §4).
Every sine step may then be shifted by up to ``Context.alignment_freedom_s`` (1.5 samples).
The shifts are nuisance parameters of the nominal replay; effects that move the timing (delay,
jerk, dynamics) are fitted without them and must beat the nominal *with* them.

The same holds for the clock rate. Without latch times the edges bound the DAQ's drift only to
about one sample over a record (≈ 120 ppm on a 4 s record at 2 kHz); the replay takes the centre
of what all steps allow together (one crystal), which may sit tens of ppm off the truth — on a
fast sine the phase then slides through the record by a fraction of a sample, a structure no
sensor has. The drift within those bounds is a nuisance too: one warp common to all steps,
fitted with the offsets. Whether the drift itself is a finding (beyond the rig's clock
tolerance) is decided by the ``clock_drift`` candidate from the same bounds.

With ``fp_latch_s`` every edge time is known below one sample, the alignment is resolved and
there is no nuisance: a sub-sample delay or lead is then evidence like any other effect.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from aatest.diagnose.candidates.base import Context, scalar_search
from aatest.diagnose.design import step_columns
from aatest.diagnose.gram import Fit
from aatest.diagnose.spec import Spec


def nominal_fit(ctx: Context, base: Spec | None = None) -> Fit:
    """Bias and scale calibrated on the data; alignment free within ±1 sample unless resolved.

    Without latch times a common offset is searched first, then every sine step's own offset
    with the linear coefficients held, then the coefficients are refitted. With them the
    loggers are taken as aligned (``Context.alignment_resolved``).
    """
    base = base or Spec()
    dt = ctx.alignment_freedom_s
    if not ctx.dynamic_steps or ctx.alignment_resolved:
        return ctx.fit(base)
    _, fit = scalar_search(ctx, lambda d: replace(base, delay_s=d, step_shift_s=()), -dt, dt,
                           list(np.linspace(-dt, dt, 9)), xtol=1e-7)
    fit = ctx.fit(refine_step_shifts(ctx, fit))
    bounds = warp_freedom_ppm(ctx)
    if bounds is None:
        return fit
    held = fit.spec
    _, fit = scalar_search(ctx, lambda w: replace(held, warp_ppm=w), *bounds,
                           list(np.linspace(*bounds, 9)), xtol=0.01)
    return ctx.fit(refine_step_shifts(ctx, fit))


def warp_freedom_ppm(ctx: Context) -> tuple[float, float] | None:
    """Warps (ppm) of the replay the sync edges leave open: None when they resolve the rate.

    The replay is synchronised at the centre of the drifts every step's edge intervals allow
    (:func:`~aatest.clocksync.edges.joint_slope_range`); a warp ``w`` of the prediction stands for a
    drift ``centre − w`` (:func:`~aatest.diagnose.candidates.logger.phase_trend_drift`), so the
    open warps are the range mirrored about the centre.
    """
    from aatest.diagnose.candidates.logger import clock_drift

    est = clock_drift(ctx)
    if est is None or est.range_ppm is None:
        return None
    lo, hi = est.drift_ppm - est.range_ppm[1], est.drift_ppm - est.range_ppm[0]
    return (lo, hi) if hi > lo else None


def _parabola_min(grid: np.ndarray, costs: np.ndarray) -> float:
    """Minimum of the parabola through the best grid point and its neighbours (within bounds).

    The residual is quadratic in a sub-sample shift, so three points locate its minimum.
    """
    i = int(np.clip(np.argmin(costs), 1, grid.size - 2))
    x, y = grid[i - 1: i + 2], costs[i - 1: i + 2]
    a, b, _ = np.polyfit(x, y, 2)
    if a <= 0:
        return float(grid[int(np.argmin(costs))])
    return float(np.clip(-b / (2 * a), grid[0], grid[-1]))


def refine_step_shifts(ctx: Context, fit: Fit) -> Spec:
    """Per-step offsets within the alignment freedom that minimise each step's residual.

    The offsets sit around an accepted ``time_delay`` (the common lag beyond the sync's
    resolution is evidence; each step's sub-sample offset around it is not), else around zero.
    """
    dt = ctx.alignment_freedom_s
    spec = fit.spec
    centre = spec.delay_s if "time_delay" in ctx.accepted else 0.0
    offsets = [spec.shift_of(s.index) - centre for s in ctx.replay.steps]
    for sr in ctx.replay.steps:
        if not sr.dynamic:
            continue

        def cost(offset: float, sr=sr) -> float:
            trial = replace(spec, delay_s=centre, step_shift_s=tuple(
                offset if i == sr.index else v for i, v in enumerate(offsets)))
            r = ctx.targets[sr.index] - step_columns(sr, ctx.info, trial, fit.names) @ fit.coef
            return float(r @ r)

        grid = np.linspace(-dt, dt, 5)
        costs = np.array([cost(g) for g in grid])
        offsets[sr.index] = _parabola_min(grid, costs)
    return replace(spec, delay_s=centre, step_shift_s=tuple(round(v, 10) for v in offsets))


#: effects that move the output's timing: the nominal's nuisances were fitted without them
TIMING_EFFECTS = frozenset({"time_delay", "sensor_dynamics", "jerk_sensitivity", "hysteresis",
                            "amplitude_damping"})


def realigned(ctx: Context, fit: Fit, effect: str) -> Fit:
    """``fit`` (``effect`` just accepted) with the alignment nuisances re-fitted for it.

    The nominal's warp and offsets were fitted while a timing effect was missing from the
    model, and they absorbed what they could of its phase (a 38 Hz sensor resonance left
    sidebands of 0.05 mV at ±0.08 Hz of the 8 Hz step). Once a timing effect is accepted the
    warp is re-fitted on it, and a transport delay takes the per-step offsets back around it:
    it is fitted as one lag common to all steps, without them (it must beat the nominal that
    has them), and each step would otherwise keep its own sub-sample misalignment as residual
    structure (3.4x the noise floor on a 4 Hz step, measured).
    """
    if effect not in TIMING_EFFECTS or ctx.alignment_resolved or not ctx.dynamic_steps:
        return fit
    bounds = warp_freedom_ppm(ctx)
    if bounds is not None:
        held = fit.spec
        _, fit = scalar_search(ctx, lambda w: replace(held, warp_ppm=w), *bounds,
                               list(np.linspace(*bounds, 9)), xtol=0.01)
    return ctx.fit(refine_step_shifts(ctx, fit)) if effect == "time_delay" else fit
