"""What every candidate effect shares: the fitting context, the result, and the helpers.

A candidate is one contract effect as an extension of the current model (``Spec``): it says
whether the data can test it at all, fits its parameters (linear ones by least squares inside
the Gram matrices, nonlinear ones by bounded optimisation seeded from the residual), and
returns the extended spec with its in-sample and held-out residual sums of squares.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy import optimize

from aatest.diagnose.column_store import fit_spec
from aatest.diagnose.gram import Fit
from aatest.diagnose.replay import Replay
from aatest.diagnose.spec import ChannelInfo, Spec
from aatest.numerics import Z95

#: logger offset (samples) a sync without latch times leaves open: ½ edge estimate + 1 rule
UNLATCHED_FREEDOM_SAMPLES = 1.5


@dataclass
class Context:
    """One sensor channel under diagnosis: data, current model and noise properties."""

    replay: Replay
    info: ChannelInfo
    targets: dict[int, np.ndarray]
    current: Fit
    #: n / n_eff: how many samples one independent noise sample spans (filtered noise)
    correlation: float = 1.0
    cache: dict[Any, Fit] = field(default_factory=dict)
    step_cache: dict[Any, Any] = field(default_factory=dict)
    #: effects accepted so far (their shape parameters are in ``current`` and stay there)
    accepted: set[str] = field(default_factory=set)
    #: one step q of the stated sensor logger's converter (V; 0 = an ideal converter): a
    #: waveform error the converter's own rounding can make is not evidence of a sensor effect
    converter_step_v: float = 0.0

    def fit(self, spec: Spec) -> Fit:
        """Fit (memoised) a spec on this channel."""
        if spec not in self.cache:
            self.cache[spec] = fit_spec(self.replay, self.info, spec, self.targets,
                                       self.step_cache)
        return self.cache[spec]

    def scale_of(self, fit: Fit) -> float:
        """K of a fit (V per °/s²); the datasheet value when the data cannot calibrate it:
        no step moves the table, or the fitted K is below a thousandth of the datasheet's.

        Why both: on a static record the acceleration column holds only rounding residue
        once a table effect (motor vibration) is in the model, and its least-squares
        coefficient is arbitrary — K = 2.6e135 V/(°/s²) was fitted on the static
        multi-position twin data, which turned the g-sensitivity into 2.7e-138 (°/s²)/g
        (truth 0.573) and wrote that K into ``--model-out``.
        """
        nominal = self.info.nominal_scale_v_per_dps2
        moving = any(step.dynamic for step in self.replay.steps)
        return fit.scale if moving and abs(fit.scale) > 1e-3 * abs(nominal) else nominal

    @property
    def sigma2(self) -> float:
        """Residual variance of the current model (V²)."""
        return self.current.sse_in / max(self.current.n - self.current.k, 1)

    @property
    def alignment_resolved(self) -> bool:
        """Whether latch times (``fp_latch_s``) resolve the logger alignment below one sample.

        Only when every step was aligned on its sync edges: a step placed by its trigger alone
        is aligned to one sample whatever the table logged.
        """
        return bool(self.replay.fp_latch) and all(s.relation is not None
                                                  for s in self.replay.steps)

    @property
    def alignment_freedom_s(self) -> float:
        """Largest logger offset (s) the sync leaves open: 0 with latch times, else 1.5 samples.

        Without latch times the edge is placed half a sample before the registering sample
        (±½ sample), and a further sub-sample offset is not evidence (docs/interfaces.md §4).
        """
        return 0.0 if self.alignment_resolved else UNLATCHED_FREEDOM_SAMPLES * self.replay.dt_s

    def within_sync_resolution(self, shift_s: float) -> bool:
        """Whether a timing shift (s) is one the sync cannot tell from a logger offset."""
        return not self.alignment_resolved and abs(shift_s) <= self.alignment_freedom_s

    @property
    def dynamic_steps(self) -> list[int]:
        return [s.index for s in self.replay.steps if s.dynamic]


@dataclass
class CandidateFit:
    """A fitted extension: the new spec and fit, its contract parameters with 95 % bounds."""

    effect: str
    fit: Fit
    parameters: dict[str, float]
    ci95: dict[str, list[float]]
    attributed_to: str = "sensor"
    extra: dict[str, Any] = field(default_factory=dict)
    #: a reason this fit cannot count as evidence, even when it improves the residual
    veto: str | None = None


def linear_ci(ctx: Context, fit: Fit, name: str,
              divide_by_scale: bool = True) -> tuple[float, list[float]]:
    """Value and 95 % interval of one linear coefficient (optionally relative to K)."""
    j = fit.names.index(name)
    sigma2 = fit.sse_in / max(fit.n - fit.k, 1) * ctx.correlation
    cov = np.linalg.pinv(fit.xtx) * sigma2
    value, u = float(fit.coef[j]), float(np.sqrt(max(cov[j, j], 0.0)))
    if divide_by_scale:
        k = ctx.scale_of(fit)
        value, u = value / k, u / abs(k)
    return value, [value - Z95 * u, value + Z95 * u]


def scalar_search(ctx: Context, make: Callable[[float], Spec], lo: float, hi: float,
                  seeds: list[float] | None = None, xtol: float | None = None) -> tuple[float, Fit]:
    """Minimise the in-sample SSE over one bounded shape parameter (grid seed + Brent)."""
    grid = np.linspace(lo, hi, 9) if seeds is None else np.asarray(seeds, dtype=float)
    values = [ctx.fit(make(float(x))).sse_in for x in grid]
    best = int(np.argmin(values))
    a = float(grid[max(best - 1, 0)])
    b = float(grid[min(best + 1, grid.size - 1)])
    if b > a:
        res = optimize.minimize_scalar(lambda x: ctx.fit(make(float(x))).sse_in, bounds=(a, b),
                                       method="bounded",
                                       options={"xatol": xtol or (b - a) * 1e-4})
        x = float(res.x)
    else:
        x = float(grid[best])
    return x, ctx.fit(make(x))


def curvature_ci(ctx: Context, make: Callable[[float], Spec], x: float, step: float,
                 lo: float = -np.inf, hi: float = np.inf) -> list[float]:
    """95 % interval of a shape parameter from the curvature of the profiled SSE.

    var(x) ≈ 2σ²·ν / (d²SSE/dx²), ν the noise correlation factor.
    """
    xm, xp = max(x - step, lo), min(x + step, hi)
    s0, sm, sp = (ctx.fit(make(v)).sse_in for v in (x, xm, xp))
    h1, h2 = x - xm, xp - x
    if h1 <= 0 or h2 <= 0:
        return [x, x]
    curv = 2.0 * (h1 * sp + h2 * sm - (h1 + h2) * s0) / (h1 * h2 * (h1 + h2))
    if curv <= 0:
        return [lo if np.isfinite(lo) else x - 10 * step, hi if np.isfinite(hi) else x + 10 * step]
    u = float(np.sqrt(2.0 * ctx.sigma2 * ctx.correlation / curv))
    return [x - Z95 * u, x + Z95 * u]


def dynamic_peak_dps2(ctx: Context) -> float:
    """Largest commanded |α| along the sensor axis in any step (°/s²)."""
    from aatest.diagnose.replay import sensor_acceleration

    peak = 0.0
    for s in ctx.replay.steps:
        if s.dynamic:
            alpha = sensor_acceleration(s, ctx.info.axis, s.time_s)[2]
            peak = max(peak, float(np.max(np.abs(alpha))))
    return peak


def base_spec(ctx: Context) -> Spec:
    return ctx.current.spec


def replace_spec(spec: Spec, **kw: Any) -> Spec:
    return replace(spec, **kw)
