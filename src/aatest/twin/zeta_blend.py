"""Blending of the ζ-grid filters of the amplitude-dependent sensor dynamics.

:func:`aatest.twin.sensor.amplitude_dynamics` weighs, sample by sample, the outputs of the two
fixed-ζ filters either side of ζ(t). These helpers find which filters carry weight up to
which sample (so a filter need not run past it) and form the weighted sum with the very float
operations of the plain Σ_k w_k·y_k over every grid filter, bit for bit.
"""

from __future__ import annotations

import numpy as np


def filters_needed(low: np.ndarray, frac: np.ndarray) -> tuple[int, np.ndarray]:
    """(k0, last): the ζ-grid filters k0, k0 + 1, … that ``amplitude_dynamics`` blends with
    a non-zero weight, as the last sample index that weights filter k0 + j (−1: none).

    Filter k weighs 1 − frac > 0 where low = k and frac where low = k − 1 (when frac > 0).
    """
    k0 = int(low.min())
    size = int(low.max()) - k0 + 2
    last = _last_index(low - k0, size)
    positive = np.flatnonzero(frac > 0.0)
    upper = _last_index(low[positive] - (k0 - 1), size, positive)
    return k0, np.maximum(last, upper)


def _last_index(values: np.ndarray, size: int, index: np.ndarray | None = None) -> np.ndarray:
    """Last position (``index[i]`` of the i-th value, default i) of each value 0…size − 1
    in ``values`` (−1 when absent; values outside the range are ignored): run ends only."""
    last = np.full(size, -1, dtype=np.int64)
    if values.size:
        ends = np.append(np.flatnonzero(values[1:] != values[:-1]), values.size - 1)
        keep = ends[values[ends] < size]
        np.maximum.at(last, values[keep], keep if index is None else index[keep])
    return last


#: runs of one grid filter pair up to which the blend works on slices (else one gather)
_BLEND_RUNS = 64


def blend(filtered: dict[int, np.ndarray], row: np.ndarray, frac: np.ndarray) -> np.ndarray:
    """(1 − frac)·y[row] + frac·y[row + 1], sample by sample, then + 0.0 (``filtered``: row →
    filter output, a prefix long enough for every sample that weighs it; a missing or
    shorter row has weight 0 where it is absent).

    The same float operations, bit for bit, as accumulating Σ_k w_k·y_k over every grid
    filter k in ascending order from zero (the other weights are exact zeros, adding ±0; the
    final + 0.0 gives the +0 that sum starts from where both terms are zero).
    """
    n = frac.size
    ends = np.append(np.flatnonzero(row[1:] != row[:-1]) + 1, n)
    if ends.size > _BLEND_RUNS:
        return _gathered(filtered, row, frac)
    out = np.subtract(1.0, frac)
    start = 0
    for end in ends.tolist():
        k = int(row[start])
        out[start:end] *= filtered[k][start:end]
        upper = filtered.get(k + 1)
        if upper is not None and min(end, upper.size) > start:
            stop = min(end, upper.size)
            out[start:stop] += frac[start:stop] * upper[start:stop]
        start = end
    out += 0.0
    return out


def _gathered(filtered: dict[int, np.ndarray], row: np.ndarray,
                    frac: np.ndarray) -> np.ndarray:
    """:func:`blend` by one gather from a (filters × samples) table (many runs)."""
    n = frac.size
    rows = np.zeros((int(row.max()) + 2, n))
    for k, y in filtered.items():
        if k < rows.shape[0]:
            rows[k, :y.size] = y
    flat = row * n
    flat += np.arange(n)
    table = rows.ravel()
    out = np.subtract(1.0, frac)
    out *= table.take(flat)
    flat += n
    upper = table.take(flat)
    upper *= frac
    out += upper
    out += 0.0
    return out
