"""Effect plugins (entry-point group ``aatest.effects``) as candidates of the selection.

Each installed :class:`aatest.effects.Effect` becomes a :class:`Candidate` like the built-in
ones: its testability comes from :meth:`~aatest.effects.Effect.testable` on what the data
exercise, its fit adds the plugin's design columns to the current spec (switched on as
``plugin:<name>``, :func:`aatest.effects.spec_token`) — linear parameters by least squares
inside the Gram matrices, shape parameters by a bounded search of the in-sample SSE — and
its :meth:`~aatest.effects.Effect.signature` may veto a fit whose physics does not match.
It then competes with the built-ins on the same held-out evidence (ΔBIC, RMS reduction).
"""

from __future__ import annotations

from collections.abc import Callable

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
from aatest.diagnose.gram import Fit
from aatest.diagnose.spec import Spec
from aatest.effects import (
    Effect,
    Excitation,
    InstalledEffect,
    column_name,
    load_effect,
    spec_token,
)

#: evaluations of the joint search over two or more shape parameters at most
MAX_SHAPE_EVALUATIONS = 60


def excitation(ctx: Context) -> Excitation:
    """What the channel's data exercise (peak |α|, range, temperature span, frequencies)."""
    steps = ctx.replay.steps
    temps = [float(np.mean(s.temperature_c)) for s in steps if s.temperature_c is not None]
    freqs = sorted({round(s.inner.frequency_hz or s.outer.frequency_hz, 9)
                    for s in steps if s.dynamic})
    peak = dynamic_peak_dps2(ctx) if any(s.dynamic for s in steps) else 0.0
    return Excitation(peak_alpha_dps2=peak, range_dps2=ctx.info.range_dps2,
                      temperature_span_c=(max(temps) - min(temps)) if len(temps) > 1 else 0.0,
                      frequencies_hz=tuple(float(f) for f in freqs if f > 0))


def _with_shape(spec: Spec, name: str, shape: dict[str, float]) -> Spec:
    """``spec`` with the plugin effect ``name`` on and its shape parameters set."""
    others = tuple(item for item in spec.plugin_shape if item[0] != name)
    entry = (name, tuple(sorted((k, round(float(v), 12)) for k, v in shape.items())))
    return replace_spec(spec.with_linear(spec_token(name)),
                        plugin_shape=(*others, entry) if shape else others)


def _search_shape(ctx: Context, eff: Effect) -> tuple[dict[str, float], Fit,
                                                       dict[str, list[float]]]:
    """Shape parameters minimising the in-sample SSE, the fit there and their 95 % bounds."""
    base = ctx.current.spec
    params = eff.shape_parameters
    bounds = [(float(p.lower), float(p.upper)) for p in params]  # type: ignore[arg-type]
    if len(params) == 1:
        (lo, hi), key = bounds[0], params[0].name

        def make(x: float) -> Spec:
            return _with_shape(base, eff.name, {key: x})

        x, fit = scalar_search(ctx, make, lo, hi)
        step = max(0.01 * abs(x), 1e-6 * (hi - lo))
        return {key: x}, fit, {key: curvature_ci(ctx, make, x, step, lo=lo, hi=hi)}

    def shape_of(v: np.ndarray) -> dict[str, float]:
        return {p.name: float(x) for p, x in zip(params, v, strict=True)}

    def cost(v: np.ndarray) -> float:
        return ctx.fit(_with_shape(base, eff.name, shape_of(v))).sse_in

    start = np.array([0.5 * (lo + hi) for lo, hi in bounds])
    res = optimize.minimize(cost, start, method="Powell", bounds=bounds,
                            options={"maxfev": MAX_SHAPE_EVALUATIONS, "xtol": 1e-4})
    shape = shape_of(res.x)
    ci: dict[str, list[float]] = {}
    for p, (lo, hi) in zip(params, bounds, strict=True):
        x = shape[p.name]

        def make_one(v: float, name: str = p.name) -> Spec:
            return _with_shape(base, eff.name, {**shape, name: v})

        ci[p.name] = curvature_ci(ctx, make_one, x, max(0.01 * abs(x), 1e-6 * (hi - lo)),
                                  lo=lo, hi=hi)
    return shape, ctx.fit(_with_shape(base, eff.name, shape)), ci


def fit_plugin(ctx: Context, installed: InstalledEffect) -> CandidateFit:
    """Fit one plugin effect on top of the current model (parameters with 95 % bounds).

    Linear parameters of an effect entering in °/s² are coefficients over K (like
    ``nonlinearity_cubic``); those entering in volts are the coefficients themselves.
    """
    eff = installed.effect
    if eff.shape_parameters:
        shape, fit, ci = _search_shape(ctx, eff)
    else:
        shape, fit, ci = {}, ctx.fit(_with_shape(ctx.current.spec, eff.name, {})), {}
    params: dict[str, float] = dict(shape)
    for p in eff.parameters:
        value, bounds = linear_ci(ctx, fit, column_name(eff.name, p.name),
                                  divide_by_scale=eff.enters == "acceleration")
        params[p.name], ci[p.name] = value, bounds
    out = CandidateFit(eff.name, fit, params, ci, attributed_to=eff.attributed_to,
                       extra={"plugin": {"distribution": installed.distribution,
                                         "version": installed.version}})
    out.veto = eff.signature(params, ci)
    return out


def fitter(installed: InstalledEffect) -> Callable[[Context], CandidateFit]:
    """The candidate's fit function for one installed effect."""
    return lambda ctx: fit_plugin(ctx, installed)


def testability(installed: InstalledEffect) -> Callable[[Context], str | None]:
    """The candidate's testability check: the plugin's own, on what the data exercise."""
    return lambda ctx: installed.effect.testable(excitation(ctx))


def joint_parameters(ctx: Context, fit: Fit, effect: str
                     ) -> tuple[dict[str, float], dict[str, list[float]]] | None:
    """A plugin effect's linear parameters and 95 % bounds read from a joint fit.

    The forward selection fits an effect on top of those accepted before it; once later
    effects are in the model, the joint fit (all effects and generic extensions together) is
    the one to report. None when ``effect`` is not a plugin effect of ``fit``.
    """
    if spec_token(effect) not in fit.spec.linear:
        return None
    eff = load_effect(effect).effect
    params: dict[str, float] = {}
    ci: dict[str, list[float]] = {}
    for p in eff.parameters:
        column = column_name(effect, p.name)
        if column not in fit.names:
            return None
        params[p.name], ci[p.name] = linear_ci(ctx, fit, column,
                                               divide_by_scale=eff.enters == "acceleration")
    return params, ci
