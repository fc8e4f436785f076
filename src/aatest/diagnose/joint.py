"""The joint model: the named spec and accepted generic extensions fitted together.

Both the generic pass (:mod:`aatest.diagnose.unexplained`) and the backward pass
(:mod:`aatest.diagnose.refit`) fit and score this model, so it lives apart from either: the
generic pass adds extensions to it, the backward pass removes named effects from it. The
design columns are appended to the named design, coefficients refitted on one fold of time
blocks and scored on the other.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from aatest.diagnose.candidates.base import Context
from aatest.diagnose.column_store import gram, step_design
from aatest.diagnose.design import column_names
from aatest.diagnose.generic import Proposal
from aatest.diagnose.gram import Fit, Gram, fit_gram, fold_products
from aatest.diagnose.replay import StepReplay
from aatest.diagnose.spec import Spec
from aatest.numerics import TINY


@dataclass
class Joint:
    """The named spec plus accepted generic extensions, fitted together."""

    spec: Spec
    generics: list[Proposal]
    fit: Fit
    #: held-out ΔBIC of each generic when it was accepted, with RMS before/after (V)
    evidence: list[dict[str, float]] = field(default_factory=list)


def _named_design(ctx: Context, spec: Spec, names: list[str], sr: StepReplay
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One step's named design: (indices into ``names`` of its non-zero columns, those
    columns as rows (u, n), the sensed acceleration α the α-shaped extensions need: the
    ``scale`` column).

    The columns come from the channel's column store (shared with forward selection), never
    as a dense matrix of every step's vibration terms, zero outside their own step.
    """
    used, x = step_design(sr, ctx.info, spec, names, ctx.targets[sr.index], ctx.step_cache)
    at = np.flatnonzero(used == names.index("scale"))
    alpha = x[at[0]] if at.size else np.zeros(sr.n)
    return used, x, alpha


def _generic_columns(sr: StepReplay, alpha: np.ndarray, generics: list[Proposal]) -> np.ndarray:
    if not generics:
        return np.zeros((sr.n, 0))
    return np.hstack([p.columns(sr, alpha) for p in generics])


def _generic_names(generics: list[Proposal], ctx: Context) -> list[str]:
    return [f"{p.key}#{j}" for p in generics for j in range(_width(ctx, p))]


#: key of the generic-column store (one named spec at a time) inside the channel's cache
_GENERIC_KEY = "generic columns"


def _store(ctx: Context, spec: Spec) -> dict[Any, Any]:
    """The generic columns and products on the named spec ``spec`` (the last one only)."""
    held = ctx.step_cache.get(_GENERIC_KEY)
    if held is None or held[0] != spec:
        held = (spec, {})
        ctx.step_cache[_GENERIC_KEY] = held
    return held[1]


def _prune(ctx: Context, keep: list[Proposal]) -> None:
    """Forget the columns of proposals not taken (their objects are kept alive by the store
    so that ``id`` stays unique while they are in it)."""
    held = ctx.step_cache.get(_GENERIC_KEY)
    if held is None:
        return
    ids = {id(p) for p in keep}
    for key in [k for k in held[1] if not set(k[1]) <= ids]:
        del held[1][key]


def _one_generic(ctx: Context, spec: Spec, names: list[str], sr: StepReplay,
                 prop: Proposal) -> tuple[np.ndarray, np.ndarray, np.ndarray, list]:
    """(columns on, the columns, named indices used, [cross, own, with y]) of one proposal on
    one step, from the store when seen on this spec."""
    store = _store(ctx, spec)
    key = (sr.index, (id(prop),))
    if key not in store:
        used, x, alpha = _named_design(ctx, spec, names, sr)
        gen = prop.columns(sr, alpha)
        on = np.flatnonzero(np.any(gen != 0.0, axis=0))  # other steps' columns are zero here
        gen = np.ascontiguousarray(gen[:, on].T)  # one column per row, as the named design
        products = [fold_products(x, gen, sr.n), fold_products(gen, gen, sr.n),
                    fold_products(gen, ctx.targets[sr.index], sr.n)] if on.size else []
        store[key] = (on, gen, used, products, prop)
    return store[key][:4]


def _pair(ctx: Context, spec: Spec, names: list[str], sr: StepReplay, a: Proposal,
          b: Proposal) -> np.ndarray:
    """Per-fold products of two proposals' columns on one step (from the store)."""
    store = _store(ctx, spec)
    key = (sr.index, (id(a), id(b)))
    if key not in store:
        ca, cb = (_one_generic(ctx, spec, names, sr, p)[1] for p in (a, b))
        store[key] = (fold_products(ca, cb, sr.n), a, b)
    return store[key][0]


def _add_generics(g: Gram, ctx: Context, spec: Spec, k: int, sr: StepReplay,
                  generics: list[Proposal]) -> None:
    """Add one step's generic blocks (with its named columns, and among themselves)."""
    names, start = g.names[:k], k
    placed: list[tuple[Proposal, np.ndarray]] = []
    for prop in generics:
        on, _, used, products = _one_generic(ctx, spec, names, sr, prop)
        cols = start + on
        start += _width(ctx, prop)
        if on.size:
            cross, own, with_y = products
            for f in (0, 1):
                g.xtx[f][np.ix_(used, cols)] += cross[f]
                g.xtx[f][np.ix_(cols, used)] += cross[f].T
                g.xtx[f][np.ix_(cols, cols)] += own[f]
                g.xty[f][cols] += with_y[f]
            for other, other_cols in placed:
                pair = _pair(ctx, spec, names, sr, other, prop)
                for f in (0, 1):
                    g.xtx[f][np.ix_(other_cols, cols)] += pair[f]
                    g.xtx[f][np.ix_(cols, other_cols)] += pair[f].T
            placed.append((prop, cols))


def _width(ctx: Context, prop: Proposal) -> int:
    """Number of columns of a proposal (the same on every step)."""
    key = ("generic width", id(prop))
    held = ctx.step_cache.get(key)
    if held is None or held[1] is not prop:
        sr = ctx.replay.steps[0]
        held = (prop.columns(sr, np.zeros(sr.n)).shape[1], prop)
        ctx.step_cache[key] = held
    return held[0]


def joint_fit(ctx: Context, spec: Spec, generics: list[Proposal]) -> Fit:
    """Named spec and generic columns fitted together (two folds of time blocks).

    The named part is the channel's cached Gram of ``spec`` (:func:`gram`); only the
    generic columns' blocks are formed here.
    """
    named = gram(ctx.replay, ctx.info, spec, ctx.targets, ctx.step_cache)
    k = len(named.names)
    names = named.names + _generic_names(generics, ctx)
    p = len(names)
    g = Gram(names, np.zeros((2, p, p)), np.zeros((2, p)), named.yty.copy(), named.count.copy())
    g.xtx[:, :k, :k] = named.xtx
    g.xty[:, :k] = named.xty
    if generics:
        for sr in ctx.replay.steps:
            _add_generics(g, ctx, spec, k, sr, generics)
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
    coef = joint.fit.coef
    out = {}
    for sr in ctx.replay.steps:
        used, x, alpha = _named_design(ctx, joint.spec, names, sr)
        model = coef[used] @ x + _generic_columns(sr, alpha, joint.generics) @ coef[len(names):]
        out[sr.index] = ctx.targets[sr.index] - model
    return out
