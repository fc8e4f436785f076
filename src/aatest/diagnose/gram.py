"""Least squares on Gram matrices over two folds: the fit and its held-out score.

Per step and per fold only XᵀX, Xᵀy and yᵀy are kept (:class:`Gram`), so fitting a model on
one fold and scoring it on the other costs a small linear solve, not a pass over the data:
the two-fold cross-validated (held-out) SSE that diagnose's selection compares.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.linalg import lapack

from aatest.diagnose.spec import Spec
from aatest.numerics import TINY

#: contiguous time blocks per step; even blocks form fold A, odd blocks fold B
BLOCKS_PER_STEP = 8


@dataclass
class Gram:
    """Sufficient statistics of a linear least-squares problem on two folds."""

    names: list[str]
    xtx: np.ndarray  # (2, p, p)
    xty: np.ndarray  # (2, p)
    yty: np.ndarray  # (2,)
    count: np.ndarray  # (2,)

    @property
    def n(self) -> int:
        return int(self.count.sum())


def fold_of(n: int) -> np.ndarray:
    """Fold (0 or 1) of each sample of an n-sample record: alternating contiguous blocks."""
    return (np.arange(n) * BLOCKS_PER_STEP // max(n, 1)) % 2


@lru_cache(maxsize=64)
def block_edges(n: int) -> np.ndarray:
    """Start indices of the contiguous time blocks of an n-sample record (and n)."""
    return np.searchsorted(np.arange(n) * BLOCKS_PER_STEP // max(n, 1),
                           np.arange(BLOCKS_PER_STEP + 1))


def fold_products(a: np.ndarray, b: np.ndarray, n: int) -> np.ndarray:
    """Per-fold a·bᵀ, shape (2, …): a, b are (·, n) or (n,) on one step's record, one column
    per row (rows are stacked by copying contiguous memory; a column-major stack of the same
    columns writes every element with a stride and cost five times as much)."""
    edges = block_edges(n)
    parts = [a[..., edges[k]:edges[k + 1]] @ b[..., edges[k]:edges[k + 1]].T
             for k in range(BLOCKS_PER_STEP)]
    return np.stack([sum(parts[0::2]), sum(parts[1::2])])


#: reciprocal condition (1-norm estimate) above which the equilibrated normal equations are
#: solved by Cholesky: both that and the SVD then err by about κ·ε ≤ 1e-8 relative, far below
#: any coefficient's uncertainty; a worse-conditioned (or rank-deficient) Gram keeps the SVD
#: and its truncation of singular values below 1e-10 of the largest
CHOLESKY_RCOND = 1e-8


def solve(xtx: np.ndarray, xty: np.ndarray) -> np.ndarray:
    """Least-squares coefficients from a Gram matrix, with column equilibration.

    Cholesky when the equilibrated Gram is well conditioned (a tenth of the SVD's cost on
    the hundred-column designs of a vibration band), else the truncated SVD.
    """
    d = np.sqrt(np.clip(np.diag(xtx), TINY, None))
    a = xtx / np.outer(d, d)
    b = xty / d
    factor, info = lapack.dpotrf(a, lower=0, clean=1)
    if info == 0:
        rcond, info = lapack.dpocon(factor, float(np.abs(a).sum(axis=0).max()))
        if info == 0 and rcond > CHOLESKY_RCOND:
            coef, info = lapack.dpotrs(factor, b, lower=0)
            if info == 0:
                return np.asarray(coef) / d
    coef, *_ = np.linalg.lstsq(a, b, rcond=1e-10)
    return coef / d


def sse(xtx: np.ndarray, xty: np.ndarray, yty: float, coef: np.ndarray) -> float:
    """Residual sum of squares of ``coef`` on the data summarised by a Gram matrix."""
    return float(yty - 2.0 * coef @ xty + coef @ xtx @ coef)


@dataclass(frozen=True)
class Fit:
    """A fitted spec: coefficients on all data, in-sample and held-out SSE."""

    spec: Spec
    names: list[str]
    coef: np.ndarray
    sse_in: float
    sse_held_out: float
    n: int
    xtx: np.ndarray

    def value(self, name: str) -> float:
        return float(self.coef[self.names.index(name)]) if name in self.names else 0.0

    @property
    def scale(self) -> float:
        return self.value("scale")

    @property
    def k(self) -> int:
        return len(self.names)


def fit_gram(g: Gram, spec: Spec) -> Fit:
    """Coefficients on both folds, plus the two-fold cross-validated (held-out) SSE."""
    xtx, xty, yty = g.xtx.sum(0), g.xty.sum(0), float(g.yty.sum())
    coef = solve(xtx, xty)
    held = 0.0
    for f in (0, 1):
        c = solve(g.xtx[f], g.xty[f])
        o = 1 - f
        held += sse(g.xtx[o], g.xty[o], float(g.yty[o]), c)
    return Fit(spec, g.names, coef, max(sse(xtx, xty, yty, coef), 0.0), max(held, 0.0), g.n, xtx)
