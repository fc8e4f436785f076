"""Residual views as SVG figures for the diagnosis report (not written to the JSON).

Four pictures per channel: residual RMS per step before/after the extended model; residual
RMS against |acceleration|, |rate|, |jerk|, temperature and time in the record; the residual
spectrum's strongest lines by class; and the worst step's residual trace before and after.
Matplotlib's object API only (no pyplot state), so rendering is safe in any process.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import LogFormatter

from aatest.diagnose.candidates.base import Context
from aatest.presentation.figures import to_svg

#: fixed margins (inches' share of the figure): a constrained layout measures every tick
#: label's extent first, which took half the drawing time of these small figures
_MARGINS = {"left": 0.11, "right": 0.98, "top": 0.88}


def _log_y(ax: Any) -> None:
    """A log y axis labelled in plain numbers (0.1, 0.2, 1): matplotlib's default labels
    are mathtext (10⁻¹), which it parses with pyparsing, building its parser on first use
    (a third of this figure's drawing time)."""
    ax.set_yscale("log")
    ax.yaxis.set_major_formatter(LogFormatter())
    ax.yaxis.set_minor_formatter(LogFormatter(labelOnlyBase=False))


def per_step_bars(views: dict[str, Any], channel: str) -> str:
    rows = views["per_step"]
    fig = Figure(figsize=(6.4, 2.8))
    fig.subplots_adjust(**_MARGINS, bottom=0.36)  # room for the rotated step names
    ax = fig.subplots()
    x = np.arange(len(rows))
    ax.bar(x - 0.2, [1e3 * r["rms_v_nominal"] for r in rows], 0.4, color="0.6", label="nominal")
    ax.bar(x + 0.2, [1e3 * r["rms_v_extended"] for r in rows], 0.4, color="C2",
           label="extended (named + generic)")
    ax.set_xticks(x, [r["step"] for r in rows], rotation=60, fontsize=7)
    ax.set_ylabel("residual RMS (mV)")
    _log_y(ax)
    ax.set_title(f"{channel}: residual per step", fontsize=9)
    ax.legend(fontsize=7)
    return to_svg(fig)


def against_panels(views: dict[str, Any], channel: str) -> str:
    against = views["against"]
    fig = Figure(figsize=(7.2, 2.6))
    fig.subplots_adjust(**_MARGINS, bottom=0.2, wspace=0.08)
    axes = fig.subplots(1, len(against), sharey=True)
    for ax, (name, bins) in zip(np.atleast_1d(axes), against.items(), strict=False):
        mids = [0.5 * (b["from"] + b["to"]) for b in bins]
        ax.plot(mids, [1e3 * b["rms_v"] for b in bins], "o-", color="C0")
        ax.set_xlabel(name, fontsize=7)
        ax.tick_params(labelsize=6)
    np.atleast_1d(axes)[0].set_ylabel("nominal residual RMS (mV)", fontsize=7)
    fig.suptitle(f"{channel}: where the nominal replay is wrong", fontsize=9)
    return to_svg(fig)


def spectrum_lines(views: dict[str, Any], channel: str) -> str | None:
    lines = views["spectrum_lines"]
    if not lines:
        return None
    fig = Figure(figsize=(6.4, 2.6))
    fig.subplots_adjust(**_MARGINS, bottom=0.2)
    ax = fig.subplots()
    classes = sorted({ln["class"].split(":")[0].split(" of")[0] for ln in lines})
    for i, cls in enumerate(classes):
        sel = [ln for ln in lines if ln["class"].startswith(cls)]
        ax.stem([ln["frequency_hz"] for ln in sel], [1e3 * ln["amplitude_v"] for ln in sel],
                linefmt=f"C{i}-", markerfmt=f"C{i}o", basefmt=" ", label=cls)
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("line amplitude (mV)")
    ax.set_title(f"{channel}: residual spectrum lines", fontsize=9)
    ax.legend(fontsize=7)
    return to_svg(fig)


def before_after_trace(ctx: Context, r0: dict[int, np.ndarray], r1: dict[int, np.ndarray]
                       ) -> str:
    """Residual of the step that improved most, nominal (``r0``) vs the extended model the
    JSON reports (``r1``: named and generic extensions), first second shown."""
    gains = {i: np.std(r0[i]) - np.std(r1[i]) for i in r0}
    k = max(gains, key=lambda i: gains[i])
    sr = next(s for s in ctx.replay.steps if s.index == k)
    n = min(sr.n, round(1.0 / sr.dt_s))
    t = sr.time_s[:n]
    fig = Figure(figsize=(6.4, 2.6))
    fig.subplots_adjust(**_MARGINS, bottom=0.2)
    ax = fig.subplots()
    ax.plot(t, 1e3 * r0[k][:n], color="0.6", lw=0.6, label="nominal")
    ax.plot(t, 1e3 * r1[k][:n], color="C2", lw=0.6, label="extended (named + generic)")
    ax.set_xlabel("time in record (s)")
    ax.set_ylabel("residual (mV)")
    ax.set_title(f"{ctx.info.channel}, step {sr.step.id}: before / after", fontsize=9)
    ax.legend(fontsize=7)
    return to_svg(fig)


def residual_figures(ctx: Context, r0: dict[int, np.ndarray], r1: dict[int, np.ndarray],
                     views: dict[str, Any]) -> dict[str, str]:
    """All figures of one channel, keyed by title (``r0``/``r1``: nominal/extended residuals)."""
    ch = ctx.info.channel
    out = {f"{ch} residual per step": per_step_bars(views, ch),
           f"{ch} residual against motion": against_panels(views, ch),
           f"{ch} before and after": before_after_trace(ctx, r0, r1)}
    lines = spectrum_lines(views, ch)
    if lines is not None:
        out[f"{ch} residual spectrum"] = lines
    return out
