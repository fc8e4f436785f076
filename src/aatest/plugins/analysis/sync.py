"""The ``sync`` analysis: the clock relation of every step, summarised for results.json."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from aatest.engine.dataset import Dataset
from aatest.engine.interfaces import AnalysisContext, AnalysisOutput, NoOptions
from aatest.results.sync import SyncResult
from aatest.sync.freeze_pulse import SyncedStep, synchronise_all


@dataclass(frozen=True)
class SyncOutput(AnalysisOutput[SyncResult]):
    """The sync result plus the synchronised steps themselves (not written to results.json);
    every analysis that ``requires`` sync reads them from ``context.upstream["sync"]``."""

    steps: tuple[SyncedStep, ...] = ()


def summarise(steps: list[SyncedStep]) -> SyncResult:
    """Overall contract keys over all steps plus a per-step list under ``steps``.

    The overall drift is the edge-weighted mean of the per-step drifts (one crystal); the
    residual is pooled over all edges; ``offset_s`` is that of the first step (each record
    has its own start, so offsets are only meaningful per step).
    """
    rel = [s.relation for s in steps]
    edges = np.array([r.edges_used for r in rel], dtype=float)
    drift = np.array([r.drift_ppm for r in rel])
    pooled_us = float(np.sqrt(np.sum(edges * np.array([r.residual_rms_us for r in rel]) ** 2)
                              / edges.sum()))
    u_drift = np.array([r.drift_u_ppm for r in rel])
    return SyncResult.model_validate({
        "drift_ppm": float(np.sum(edges * drift) / edges.sum()),
        "offset_s": rel[0].offset_s,
        "residual_rms_us": pooled_us,
        "edges_used": int(edges.sum()),
        "drift_u_ppm": float(np.sqrt(np.sum((edges * u_drift) ** 2)) / edges.sum()),
        "drift_spread_ppm": float(np.std(drift, ddof=1)) if drift.size > 1 else 0.0,
        "steps": [{"step": s.step.id, **s.relation.as_dict()} for s in steps],
    })


def sync_figure(steps: list[SyncedStep]) -> str:
    """Drift and clock-relation residual of every step (one crystal: a flat drift line)."""
    from aatest.plugins.analysis._common import new_figure, to_svg

    fig, ax = new_figure(2, height_in=2.0)
    idx = np.arange(len(steps))
    ax[0, 0].plot(idx, [s.relation.drift_ppm for s in steps], "o", ms=3)
    ax[0, 0].set(ylabel="drift / ppm", title="logger synchronisation")
    ax[1, 0].plot(idx, [s.relation.residual_rms_us for s in steps], "o", ms=3)
    ax[1, 0].set(xlabel="step", ylabel="residual RMS / µs")
    fig.tight_layout()
    return to_svg(fig)


class SyncAnalysis:
    """Freeze-pulse synchronisation of every recorded step; the steps go to its dependants."""

    key: ClassVar[str] = "sync"
    requires: ClassVar[tuple[str, ...]] = ()
    Options: ClassVar[type[NoOptions]] = NoOptions
    Result: ClassVar[type[SyncResult]] = SyncResult

    def applies_to(self, data: Dataset) -> bool:
        return any(s.step.recorded for s in data.steps)

    def run(self, data: Dataset, context: AnalysisContext) -> SyncOutput:
        steps = synchronise_all(data)
        return SyncOutput(result=summarise(steps), figures={"sync": sync_figure(steps)},
                          steps=tuple(steps))
