"""The fleet pages' plots: drift with its interval, and I-MR control charts (SVG strings).

Drawn like the report figures: matplotlib's object API (no pyplot state, safe from the
station's worker threads), rendered by :mod:`aatest.presentation.figures`, so the same data
give the same file (stable element ids, no date).
"""

from __future__ import annotations

from typing import Any

import matplotlib
import matplotlib.dates as mdates
import numpy as np
from matplotlib.figure import Figure
from scipy import stats

from aatest.fleet.control import ControlChart
from aatest.fleet.interval import DAYS_PER_MONTH, DriftFit, IntervalRecommendation
from aatest.presentation.figures import STYLE, to_svg

_STYLE: dict[Any, Any] = dict(STYLE)
#: the drift plot looks this far past the longest observed interval (or the recommendation)
_AHEAD = 1.5
#: the band drawn about the fitted drift: the two-sided 95 % prediction interval
_BAND = 0.975


def _svg(fig: Figure) -> str:
    return to_svg(fig, tight=True, inline=True)


def drift_plot(fit: DriftFit, recommendation: IntervalRecommendation | None,
               label: str, unit: str) -> str:
    """Deviation against months since calibration with the fit, its 95 % prediction band and
    the tolerance relative to the as-left value; below it, the reliability ``R(t)``."""
    with matplotlib.rc_context(_STYLE):
        rows = 2 if recommendation is not None else 1
        fig = Figure(figsize=(7.0, 2.6 * rows))
        axes = fig.subplots(rows, 1, sharex=True, squeeze=False)[:, 0]
        t = np.array([s.elapsed_days for s in fit.samples])
        y = np.array([s.deviation for s in fit.samples])
        u = np.array([s.u_deviation or 0.0 for s in fit.samples])
        end = max(t.max(), (recommendation.days or 0.0) if recommendation else 0.0) * _AHEAD
        grid = np.linspace(0.0, end, 200)
        k = stats.t.ppf(_BAND, fit.dof)
        band = k * fit.u_prediction(grid)
        axes[0].errorbar(t / DAYS_PER_MONTH, y, yerr=2 * u, fmt="o", capsize=3,
                         label="as-found − as-left ± U")
        axes[0].plot(grid / DAYS_PER_MONTH, fit.deviation(grid), color="tab:gray",
                     label="fitted drift")
        axes[0].fill_between(grid / DAYS_PER_MONTH, fit.deviation(grid) - band,
                             fit.deviation(grid) + band, color="tab:gray", alpha=0.2,
                             label="95 % prediction")
        axes[0].set_ylabel(f"deviation [{unit}]")
        if recommendation is not None:
            _reliability_axes(axes, grid, recommendation)
        axes[-1].set_xlabel("months since calibration")
        axes[0].set_title(label, fontsize=9)
        axes[0].legend(fontsize="small")
        return _svg(fig)


def _reliability_axes(axes: Any, grid: np.ndarray,
                      recommendation: IntervalRecommendation) -> None:
    for bound in recommendation.limits:
        axes[0].axhline(bound - recommendation.x_left, color="tab:red", linestyle="--",
                        linewidth=1)
    axes[0].plot([], [], color="tab:red", linestyle="--", label="tolerance (from as-left)")
    axes[1].plot(grid / DAYS_PER_MONTH, recommendation.reliability(grid), color="tab:blue")
    axes[1].axhline(recommendation.target, color="tab:green", linestyle=":",
                    label=f"target {recommendation.target:g}")
    if recommendation.days is not None:
        for ax in axes:
            ax.axvline(recommendation.days / DAYS_PER_MONTH, color="tab:green", linewidth=1)
    axes[1].set_ylabel("reliability R(t)")
    axes[1].legend(fontsize="small")


def control_plot(chart: ControlChart, label: str, unit: str) -> str:
    """The individuals chart (centre line, ±3σ limits, flagged points in red) over the
    moving-range chart (MR̄ and its upper limit)."""
    with matplotlib.rc_context(_STYLE):
        fig = Figure(figsize=(7.0, 4.2))
        top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=(2, 1))
        days = mdates.date2num(list(chart.moments))
        flagged = chart.flagged()
        top.plot(days, chart.values, marker="o", color="tab:blue", linewidth=1)
        top.plot(days[flagged], chart.values[flagged], "o", color="tab:red",
                 label="out of control")
        top.axhline(chart.center, color="tab:gray", label="centre")
        for bound in chart.limits:
            top.axhline(bound, color="tab:red", linestyle="--", linewidth=1)
        top.set_ylabel(f"{label} [{unit}]")
        top.legend(fontsize="small")
        bottom.plot(days[1:], chart.moving_ranges, marker=".", color="tab:blue", linewidth=1)
        bottom.axhline(chart.mr_bar, color="tab:gray")
        bottom.axhline(chart.mr_ucl, color="tab:red", linestyle="--", linewidth=1)
        bottom.set_ylabel("moving range")
        locator = mdates.AutoDateLocator(minticks=3, maxticks=8)
        bottom.xaxis.set_major_locator(locator)
        bottom.xaxis.set_major_formatter(mdates.ConciseDateFormatter(locator))
        return _svg(fig)
