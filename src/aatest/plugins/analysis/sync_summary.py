"""The ``sync`` result: the steps' clock relations summarised for results.json, and its figure.

Why a module of its own: the summary reads only each step's planned step and clock relation
(:class:`Related`, or a synchronised step), whichever way the pass made them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from aatest.clocksync.edges import joint_slope_range
from aatest.clocksync.freeze_pulse import ClockRelation, SyncedStep
from aatest.engine.steps import PlannedStep
from aatest.presentation.figures import new_figure, tight_layout, to_svg
from aatest.results.sync import SyncResult


@dataclass(frozen=True)
class Related:
    """A step's planned step and clock relation: what the summary reads of a synced step."""

    step: PlannedStep
    relation: ClockRelation


def joint_drift(relations: Sequence[ClockRelation]) -> tuple[float, float] | None:
    """(drift ppm, standard uncertainty ppm) common to the steps fitted without latch times:
    the centre of :func:`~aatest.clocksync.edges.joint_slope_range`, uniform over it. None
    when there is none (the edge-weighted mean then stands, with the spread beside it)."""
    joint = joint_slope_range(relations)
    if joint is None:
        return None
    lo, hi = joint
    return (0.5 * (lo + hi) - 1.0) * 1e6, (hi - lo) / float(np.sqrt(12.0)) * 1e6


def summarise(steps: Sequence[SyncedStep | Related]) -> SyncResult:
    """Overall contract keys over all steps plus a per-step list under ``steps``.

    The overall drift is the edge-weighted mean of the per-step drifts (one crystal), or
    without latch times the centre of the slopes every step allows (:func:`joint_drift`); the
    residual is pooled over all edges; ``offset_s`` is that of the first step (each record
    has its own start, so offsets are only meaningful per step).
    """
    rel = [s.relation for s in steps]
    edges = np.array([r.edges_used for r in rel], dtype=float)
    drift = np.array([r.drift_ppm for r in rel])
    pooled_us = float(np.sqrt(np.sum(edges * np.array([r.residual_rms_us for r in rel]) ** 2)
                              / edges.sum()))
    u_drift = np.array([r.drift_u_ppm for r in rel])
    overall = float(np.sum(edges * drift) / edges.sum())
    overall_u = float(np.sqrt(np.sum((edges * u_drift) ** 2)) / edges.sum())
    joint = joint_drift(rel) if not any(r.latched for r in rel) else None
    if joint is not None:
        overall, overall_u = joint
    return SyncResult.model_validate({
        "drift_ppm": overall,
        "offset_s": rel[0].offset_s,
        "residual_rms_us": pooled_us,
        "edges_used": int(edges.sum()),
        "drift_u_ppm": overall_u,
        "drift_spread_ppm": float(np.std(drift, ddof=1)) if drift.size > 1 else 0.0,
        "steps": [{"step": s.step.id, **s.relation.as_dict()} for s in steps],
    })


def sync_figure(steps: Sequence[SyncedStep | Related]) -> str:
    """Drift and clock-relation residual of every step (one crystal: a flat drift line)."""
    return sync_plot(*sync_plotted(steps))


def sync_plotted(steps: Sequence[SyncedStep | Related]) -> tuple[list[float], list[float]]:
    """What :func:`sync_plot` draws of ``steps``: each one's drift (ppm) and residual RMS (µs)."""
    return ([s.relation.drift_ppm for s in steps], [s.relation.residual_rms_us for s in steps])


def sync_plot(drift_ppm: list[float], residual_rms_us: list[float]) -> str:
    """:func:`sync_figure` of the steps' drifts (ppm) and residuals (µs), one per step."""
    fig, ax = new_figure(2, height_in=2.0)
    idx = np.arange(len(drift_ppm))
    ax[0, 0].plot(idx, drift_ppm, "o", ms=3)
    ax[0, 0].set(ylabel="drift / ppm", title="logger synchronisation")
    ax[1, 0].plot(idx, residual_rms_us, "o", ms=3)
    ax[1, 0].set(xlabel="step", ylabel="residual RMS / µs")
    tight_layout(fig)
    return to_svg(fig)
