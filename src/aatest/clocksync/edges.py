"""Pairing freeze-pulse edges, and the clock relation when the table logs no latch times.

Pairing. Edges are paired by time, nearest DAQ edge to each table edge, in windows that double
from one second to the whole record, each window predicted by the straight line fitted to the
pairs of the one before. A line fitted to a window of length W errs by about one sample per W
of extrapolation even when every edge carries the full ±½-sample quantisation of a table
without latch times, so the next window (2·W) is predicted within a few samples — far inside
the half pulse period (5 ms at 100 Hz) that makes the pairing unambiguous.

Without ``fp_latch_s`` the table only says at which of its samples it registered an edge: one
controller cycle after the cycle the edge fell in (docs/method.md §2), so the true edge lies
between two and one table samples before the registering row. Every edge is then an interval,
not a point, and the clock relation is the set of lines ``t_table = c + b·x`` that pass through
every interval (a convex set). Least squares through the interval centres is biased by the
sample pattern: table and DAQ sample on nearly the same grid, so the quantisation error is not
random from edge to edge but a sawtooth that moves by ``drift·period`` per edge and jumps by
one sample where the edge crosses a table sample ("slips"). Where such natural slips occur they
fix the drift precisely; where none occurs the drift is only bounded (to about one sample over
the record). The estimate is the centre of the feasible set and its standard uncertainty that
of a uniform distribution over it: honest in both cases, which ``T/√12/√N`` (independent
errors) is not for commensurate clocks. Where the pulse period is not a whole number of table
samples, the edges take many positions in their sample (a vernier) and the same feasible set
uses them: the drift is then fixed to a few times the jitter allowance over the record (≈ 8.5
ppm wide over 8 s at any drift), no separate estimator needed. The twin's (and a DAQ-generated
pulse's) clocks are commensurate by construction, 20 samples per pulse. A registration one
sample off the pattern (a late controller cycle, a generator's slip) is detected against its
neighbours and corrected before the fit.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy.ndimage import median_filter
from scipy.optimize import brentq, minimize_scalar

from aatest.engine.errors import AnalysisError

if TYPE_CHECKING:
    from aatest.clocksync.relation import ClockRelation

#: the true edge lies between this many table samples before the registering row (docs/method.md
#: §2: registered in the controller cycle after the one the edge falls in)
LAG_SAMPLES = (1.0, 2.0)
#: allowance for the pulse edges' timing jitter against the sample clocks (≈3 µs RMS measured,
#: docs/method.md §2; four times that keeps every edge of a 10⁵-edge record inside its interval)
JITTER_ALLOWANCE_S = 12e-6
#: a paired edge must lie within this fraction of the pulse period of its prediction
PAIR_TOLERANCE_PERIODS = 0.3
#: neighbours a registration is compared with when looking for a slip (odd)
SLIP_WINDOW = 9
#: first pairing window, s (the coarse offset is good to about a sample there)
FIRST_WINDOW_S = 1.0
MIN_EDGES = 3
#: at least this share of the DAQ edges inside the table record must find a table edge
_MIN_PAIRED_FRACTION = 0.9


@dataclass(frozen=True)
class Paired:
    """Paired edges: table edge times (centre estimates, s), DAQ edge times (s); ``fit``, when
    known, is :func:`line_fit` of exactly these two arrays (the last pairing window fitted
    them already: :func:`aatest.clocksync.clock_fit.fit_clock_relation` takes it instead of
    solving the same least squares again)."""

    t_table: np.ndarray
    t_daq: np.ndarray
    fit: tuple[np.ndarray, np.ndarray] | None = None


def _match(t_table: np.ndarray, t_pred: np.ndarray, tol_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Index of the nearest predicted DAQ edge for every table edge, and which are within tol.

    Each distance ``|t_pred[k] − t_table|`` is computed once and the nearer one kept (the same
    IEEE operations as choosing the index first and measuring again): pairing runs this on
    every doubling window.
    """
    k = np.searchsorted(t_pred, t_table)
    np.clip(k, 1, t_pred.size - 1, out=k)
    before = np.subtract(t_pred[k - 1], t_table)
    np.abs(before, out=before)
    after = np.subtract(t_pred[k], t_table)
    np.abs(after, out=after)
    nearer = before < after
    k -= nearer
    return np.where(nearer, before, after) < tol_s, k


def line_fit(t_table: np.ndarray, t_daq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares ``t_table = c0 + c1·(t_daq − t_daq[0])``: coefficients and residuals."""
    design = np.column_stack([np.ones_like(t_daq), t_daq - t_daq[0]])
    coef, *_ = np.linalg.lstsq(design, t_table, rcond=None)
    return coef, t_table - design @ coef


def _robust_line(tt: np.ndarray, td: np.ndarray, floor_s: float
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Line through the pairs after dropping those far off a first fit; (coef, kept mask,
    the first fit's residuals when every pair is kept, else None).

    Every pair within ``floor_s`` of the first fit is kept whatever the median absolute
    deviation (the threshold is at least ``floor_s``; such residuals are finite, so is the
    deviation), so the two medians are only taken when some residual lies beyond it: with
    latch times almost never (µs residuals against a floor of 1.5 table samples), and they
    were two sorts per pairing window, a third of the run-time check.
    """
    coef, res = line_fit(tt, td)
    if bool(np.all(np.abs(res) <= floor_s)):
        return coef, np.ones(res.size, dtype=bool), res
    spread = np.subtract(res, _median(res))
    mad = 1.4826 * _median(np.abs(spread, out=spread))
    keep = np.abs(res) <= max(5.0 * mad, floor_s)
    if keep.sum() >= MIN_EDGES and not keep.all():
        coef, _ = line_fit(tt[keep], td[keep])
        coef = np.array([coef[0] - coef[1] * (td[keep][0] - td[0]), coef[1]])
    return coef, keep, (res if keep.all() else None)


def _median(x: np.ndarray) -> float:
    """``np.median`` of a 1-D float array: the same middle order statistic(s)
    and, for an even size, their sum ÷ 2 as ``np.mean`` forms it.

    Why: the robust line takes two medians per pairing window, and NumPy's SIMD sort of a
    few thousand residuals takes less than half the time of the partition ``np.median``
    uses (the order statistics are the same numbers whichever puts them in place).
    """
    half = x.size // 2
    ordered = np.sort(x)
    if x.size == 0 or np.isnan(ordered[-1]):  # (NaN sorts last) NumPy's own answer
        return float(np.median(x))
    if x.size % 2:
        return float(ordered[half])
    return float(np.add.reduce(ordered[half - 1: half + 1])) / 2.0


def _one_to_one(k: np.ndarray) -> bool:
    """Whether no DAQ edge index repeats in ``k``.

    Why not ``np.unique``: its sort (or hash) of every window's indices was a third of
    pairing; the indices of time-ordered table edges rise, so strictly rising says the same
    in one comparison pass (anything else is decided by ``np.unique``, as before).
    """
    if bool(np.all(k[1:] > k[:-1])):  # (true for fewer than two)
        return True
    return bool(np.unique(k).size == k.size)


def pair_edges(step_id: str, t_table: np.ndarray, t_daq: np.ndarray, period_s: float,
               offset0: float | None, table_dt_s: float) -> Paired:
    """Pair every table edge with its DAQ edge in doubling windows (module docstring).

    Raises
    ------
    AnalysisError
        When a window's edges cannot be paired one to one.
    """
    tol_s = PAIR_TOLERANCE_PERIODS * period_s
    coef = np.array([t_daq[0] + (t_table[0] - t_daq[0] if offset0 is None else offset0), 1.0])
    x_daq = t_daq - t_daq[0]
    ordered = bool(np.all(t_table[1:] >= t_table[:-1]))  # (true for one edge)
    window_s = FIRST_WINDOW_S
    while True:
        sel = _window(t_table, t_table[0] + window_s, ordered)
        in_window = t_table[sel]
        ok, k = _match(in_window, coef[0] + coef[1] * x_daq, tol_s)
        k_ok = k[ok]
        if k_ok.size < MIN_EDGES or not _one_to_one(k_ok):
            raise AnalysisError(f"step {step_id}: sync edges inconsistent (cannot pair edges)")
        tt, td = in_window[ok], t_daq[k_ok]
        fit, keep, res = _robust_line(tt, td, 1.5 * table_dt_s)
        if in_window.size == t_table.size:
            if res is not None:  # all kept: the pairs and their line as fitted
                return Paired(tt, td, (fit, res))
            return Paired(tt[keep], td[keep])
        coef = np.array([fit[0] - fit[1] * (td[0] - t_daq[0]), fit[1]])
        window_s *= 2.0


def _window(t_table: np.ndarray, end_s: float, ordered: bool) -> slice | np.ndarray:
    """Which table edges lie at or before ``end_s``: a leading slice when the edges are in time
    ``ordered`` (the usual case: no copy, found by bisection), else the mask ``t_table <= end_s``
    (NaN-free sorted edges give the same selection either way)."""
    if ordered:
        return slice(0, int(np.searchsorted(t_table, end_s, side="right")))
    return t_table <= end_s


def correct_slips(registered_s: np.ndarray, t_daq: np.ndarray, dt_s: float
                  ) -> tuple[np.ndarray, int]:
    """Registration times with one-off slips undone, and how many were.

    The registrations' residual from a straight line is a sawtooth of one sample's height whose
    natural jumps persist; a slip is a registration a whole number of samples off its
    neighbours' level (a running median keeps the jumps and drops the slips).
    """
    if registered_s.size < SLIP_WINDOW:
        return registered_s, 0
    _, res = line_fit(registered_s, t_daq)
    level = median_filter(res, size=SLIP_WINDOW, mode="nearest")
    slip = np.round((res - level) / dt_s)
    return registered_s - slip * dt_s, int(np.count_nonzero(slip))


@dataclass(frozen=True)
class IntervalFit:
    """The feasible set's centre and extent: slope ``b`` and table time ``c`` at ``x = 0``.

    ``x`` is the DAQ edge time relative to ``x0_s``; ``mid_range_s`` the extent of the relation's
    table time at the record's centre ``x_mid_s`` over the feasible set.
    """

    x0_s: float
    slope: float
    slope_range: tuple[float, float]
    intercept_s: float
    intercept_range_s: tuple[float, float]
    x_mid_s: float
    mid_range_s: tuple[float, float]
    residual_rms_s: float


def _gap(lo: np.ndarray, hi: np.ndarray, x: np.ndarray, b: float) -> float:
    """How far the intervals miss a common line of slope ``b`` (≤ 0: some line hits all)."""
    return float(np.max(lo - b * x) - np.min(hi - b * x))


def _slope_range(lo: np.ndarray, hi: np.ndarray, x: np.ndarray, b0: float, step_id: str
                 ) -> tuple[float, float]:
    """The interval of slopes some line through every edge interval has (g(b) ≤ 0, g convex)."""
    span = float(x[-1] - x[0])
    width = float(np.max(hi - lo))  # x sorted
    reach = 4.0 * width / max(span, 1e-9) + 1e-9
    best = minimize_scalar(lambda b: _gap(lo, hi, x, b), bounds=(b0 - reach, b0 + reach),
                           method="bounded", options={"xatol": 1e-13})
    b_best = float(best.x)
    if _gap(lo, hi, x, b_best) > 0.0:
        raise AnalysisError(
            f"step {step_id}: sync edges inconsistent — no clock relation keeps every edge "
            f"within its registering sample (misses by {_gap(lo, hi, x, b_best) * 1e6:.0f} µs)")
    ends = []
    for far in (b0 - reach, b0 + reach):
        if _gap(lo, hi, x, far) <= 0.0:
            ends.append(far)
        else:
            ends.append(brentq(lambda b: _gap(lo, hi, x, b), min(far, b_best),
                               max(far, b_best), xtol=1e-14))
    return float(min(ends)), float(max(ends))


def interval_fit(step_id: str, registered_s: np.ndarray, t_daq: np.ndarray, dt_s: float,
                 slope_range: tuple[float, float] | None = None,
                 pinned: tuple[float, float, float] | None = None) -> IntervalFit:
    """Lines through every edge's interval (module docstring): centre and extent.

    Parameters
    ----------
    registered_s
        Table times of the rows that registered the edges (slips corrected).
    t_daq
        DAQ times of the paired edges.
    dt_s
        Table sample period.
    slope_range
        Slopes allowed by other steps of the same crystal (joint fit), intersected with this
        step's own.
    pinned
        One more interval the line must pass, ``(DAQ time, table time low, high)`` (s): the
        trigger, which starts the table log at one of the DAQ's samples.
    """
    x0 = float(t_daq[0])
    x = t_daq - x0
    lo = registered_s - LAG_SAMPLES[1] * dt_s - JITTER_ALLOWANCE_S
    hi = registered_s - LAG_SAMPLES[0] * dt_s + JITTER_ALLOWANCE_S
    if pinned is not None:
        x = np.append(x, pinned[0] - x0)
        lo, hi = np.append(lo, pinned[1]), np.append(hi, pinned[2])
        order = np.argsort(x, kind="stable")
        x, lo, hi = x[order], lo[order], hi[order]
    b0 = float(line_fit(0.5 * (lo + hi), x)[0][1])
    b_lo, b_hi = _slope_range(lo, hi, x, b0, step_id)
    if slope_range is not None and max(b_lo, slope_range[0]) <= min(b_hi, slope_range[1]):
        b_lo, b_hi = max(b_lo, slope_range[0]), min(b_hi, slope_range[1])
    b = 0.5 * (b_lo + b_hi)
    c_lo, c_hi = float(np.max(lo - b * x)), float(np.min(hi - b * x))
    x_mid = 0.5 * float(x[-1] + x[0])
    grid = np.linspace(b_lo, b_hi, 17)[:, None]
    mid_lo = float(np.min(np.max(lo - grid * (x - x_mid), axis=1)))
    mid_hi = float(np.max(np.min(hi - grid * (x - x_mid), axis=1)))
    c = 0.5 * (c_lo + c_hi)
    centre = 0.5 * (lo + hi)
    residual = centre - (c + b * x)
    return IntervalFit(x0, b, (b_lo, b_hi), c, (c_lo, c_hi), x_mid, (mid_lo, mid_hi),
                       float(np.sqrt(np.mean(residual**2))))


def check_counts(step_id: str, t_table: np.ndarray, t_daq: np.ndarray) -> float:
    """The DAQ's pulse period (s), once both logs have enough edges to fit a line."""
    if t_table.size < MIN_EDGES or t_daq.size < MIN_EDGES:
        raise AnalysisError(
            f"step {step_id}: sync edges missing ({t_table.size} on the table, "
            f"{t_daq.size} on the DAQ; need ≥ {MIN_EDGES}) — check the freeze-pulse wiring"
        )
    return _median(np.diff(t_daq))


def check_paired(step_id: str, paired: int, t_table: np.ndarray, t_daq: np.ndarray,
                  coef: np.ndarray, worst_s: float, tol_s: float) -> None:
    """Refuse a relation that paired too few of the DAQ edges inside the table record."""
    t_pred = coef[0] + coef[1] * (t_daq - t_daq[0])
    inside = int(((t_pred >= t_table[0]) & (t_pred <= t_table[-1])).sum())
    offered = min(inside, t_table.size)  # edges without a latch time are not offered
    if paired < _MIN_PAIRED_FRACTION * offered or worst_s > tol_s:
        raise AnalysisError(
            f"step {step_id}: sync edges inconsistent — {paired} of {inside} DAQ "
            f"edges paired, worst residual {worst_s * 1e6:.0f} µs"
        )


def joint_slope_range(relations: Sequence[ClockRelation]) -> tuple[float, float] | None:
    """Slopes (1 + drift) every step fitted without latch times allows: one crystal drives
    the DAQ through every step, so its rate lies in each step's range (a short step, or one
    whose edges never cross a table sample, is bounded by the others). None when no step was
    fitted that way or the ranges do not meet (the rate changed between records)."""
    ranges = [r.slope_range for r in relations if not r.latched and r.slope_range is not None]
    if not ranges:
        return None
    lo, hi = max(r[0] for r in ranges), min(r[1] for r in ranges)
    return (lo, hi) if lo <= hi else None
