"""Logger alignment in the nominal model: what the sync pulse resolves, and what it does not.

Without ``fp_latch_s`` the table registers an edge at its next sample, so the pulse aligns the
loggers to about one sample: the edge estimate itself is uncertain by ±½ sample, and on top of
it an offset smaller than one sample is not evidence of ``time_delay`` (docs/interfaces.md §4).
Every sine step may then be shifted by up to ``Context.alignment_freedom_s`` (1.5 samples).
The shifts are nuisance parameters of the nominal replay; effects that move the timing (delay,
jerk, dynamics) are fitted without them and must beat the nominal *with* them.

With ``fp_latch_s`` every edge time is known below one sample, the alignment is resolved and
there is no nuisance: a sub-sample delay or lead is then evidence like any other effect.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from aatest.diagnose.design import Fit, Spec, step_columns
from aatest.diagnose.effects.base import Context, scalar_search


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
    return ctx.fit(refine_step_shifts(ctx, fit))


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
    """Per-step offsets (total shift within the alignment freedom) that minimise each step's
    residual."""
    dt = ctx.alignment_freedom_s
    spec = fit.spec
    shifts = [spec.shift_of(s.index) for s in ctx.replay.steps]
    for sr in ctx.replay.steps:
        if not sr.dynamic:
            continue

        def cost(total: float, sr=sr) -> float:
            trial = replace(spec, delay_s=0.0, step_shift_s=tuple(
                total if i == sr.index else v for i, v in enumerate(shifts)))
            r = ctx.targets[sr.index] - step_columns(sr, ctx.info, trial, fit.names) @ fit.coef
            return float(r @ r)

        grid = np.linspace(-dt, dt, 5)
        costs = np.array([cost(g) for g in grid])
        shifts[sr.index] = _parabola_min(grid, costs)
    return replace(spec, delay_s=0.0, step_shift_s=tuple(round(v, 10) for v in shifts))
