"""The joint model: the named spec and accepted generic extensions fitted together.

Both the generic pass (:mod:`aatest.diagnose.unexplained`) and the backward pass
(:mod:`aatest.diagnose.refit`) fit and score this model, so it lives apart from either: the
generic pass adds extensions to it, the backward pass removes named effects from it. The
design columns are appended to the named design, coefficients refitted on one fold of time
blocks and scored on the other.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from aatest.diagnose.candidates.base import Context
from aatest.diagnose.design import (
    Fit,
    Gram,
    Spec,
    column_names,
    fit_gram,
    fold_of,
    step_columns,
)
from aatest.diagnose.generic import Proposal
from aatest.diagnose.replay import StepReplay
from aatest.numerics import TINY


@dataclass
class Joint:
    """The named spec plus accepted generic extensions, fitted together."""

    spec: Spec
    generics: list[Proposal]
    fit: Fit
    #: held-out ΔBIC of each generic when it was accepted, with RMS before/after (V)
    evidence: list[dict[str, float]] = field(default_factory=list)


def _named_columns(ctx: Context, spec: Spec, names: list[str], sr: StepReplay) -> np.ndarray:
    """One step's named design (cached: re-used by every proposal tried on ``spec``)."""
    key = ("named design", spec, sr.index)
    if key not in ctx.step_cache:
        ctx.step_cache[key] = step_columns(sr, ctx.info, spec, names)
    return ctx.step_cache[key]


def _named_gram(ctx: Context, spec: Spec, names: list[str], sr: StepReplay) -> list[tuple]:
    """Per-fold (XᵀX, Xᵀy, yᵀy, count) of one step's named design (cached)."""
    key = ("named gram", spec, sr.index)
    if key not in ctx.step_cache:
        x, y, folds = _named_columns(ctx, spec, names, sr), ctx.targets[sr.index], fold_of(sr.n)
        ctx.step_cache[key] = [(x[m].T @ x[m], x[m].T @ y[m], float(y[m] @ y[m]), int(m.sum()))
                               for m in (folds == 0, folds == 1)]
    return ctx.step_cache[key]


def _generic_columns(sr: StepReplay, alpha: np.ndarray, generics: list[Proposal]) -> np.ndarray:
    if not generics:
        return np.zeros((sr.n, 0))
    return np.hstack([p.columns(sr, alpha) for p in generics])


def _generic_names(generics: list[Proposal], ctx: Context) -> list[str]:
    sr = ctx.replay.steps[0]
    return [f"{p.key}#{j}" for p in generics
            for j in range(p.columns(sr, np.zeros(sr.n)).shape[1])]


def _add_step(g: Gram, ctx: Context, spec: Spec, k: int, sr: StepReplay,
              generics: list[Proposal]) -> None:
    """Add one step to the joint Gram: cached named blocks, then the generic blocks."""
    x = _named_columns(ctx, spec, g.names[:k], sr)
    gen = _generic_columns(sr, x[:, 1], generics)
    used = np.flatnonzero(np.any(gen != 0.0, axis=0))  # other steps' columns are zero here
    gen, cols = gen[:, used], k + used
    y, folds = ctx.targets[sr.index], fold_of(sr.n)
    for f, (xtx, xty, yty, cnt) in enumerate(_named_gram(ctx, spec, g.names[:k], sr)):
        g.xtx[f][:k, :k] += xtx
        g.xty[f][:k] += xty
        g.yty[f] += yty
        g.count[f] += cnt
        if used.size:
            m = folds == f
            xm, gm = x[m], gen[m]
            cross = xm.T @ gm
            g.xtx[f][:k, cols] += cross
            g.xtx[f][cols, :k] += cross.T
            g.xtx[f][np.ix_(cols, cols)] += gm.T @ gm
            g.xty[f][cols] += gm.T @ y[m]


def joint_fit(ctx: Context, spec: Spec, generics: list[Proposal]) -> Fit:
    """Named spec and generic columns fitted together (two folds of time blocks)."""
    named = column_names(spec, ctx.replay)
    names = named + _generic_names(generics, ctx)
    p = len(names)
    g = Gram(names, np.zeros((2, p, p)), np.zeros((2, p)), np.zeros(2), np.zeros(2))
    for sr in ctx.replay.steps:
        _add_step(g, ctx, spec, len(named), sr, generics)
    return fit_gram(g, spec)


def held_out_rmse(fit: Fit) -> float:
    """Held-out RMS residual (V)."""
    return float(np.sqrt(fit.sse_held_out / max(fit.n, 1)))


def bic_change(ctx: Context, new: Fit, old: Fit, extra_params: int) -> float:
    """BIC(new) − BIC(old) on held-out SSE with n_eff independent samples."""
    n_eff = new.n / ctx.correlation
    dk = new.k - old.k + extra_params
    ratio = max(new.sse_held_out, TINY) / max(old.sse_held_out, TINY)
    return float(n_eff * np.log(ratio) + dk * np.log(n_eff))


def joint_residuals(ctx: Context, joint: Joint) -> dict[int, np.ndarray]:
    """Measured − (named model + generic extensions), per step index (V)."""
    names = column_names(joint.spec, ctx.replay)
    out = {}
    for sr in ctx.replay.steps:
        x = _named_columns(ctx, joint.spec, names, sr)
        full = np.hstack([x, _generic_columns(sr, x[:, 1], joint.generics)])
        out[sr.index] = ctx.targets[sr.index] - full @ joint.fit.coef
    return out
