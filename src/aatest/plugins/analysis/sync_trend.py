"""The latch-less refit: every step's clock relation narrowed by the sine steps' phase trend.

Why a module of its own: without latch times the edges only bound a step's drift; the phase
trend of the sine steps (:mod:`aatest.clocksync.phase_trend`), measured during the sync pass
(:func:`watch_trends`), is pooled over the steps and each step's relation refitted inside it
(:func:`narrowed_by_trend`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

from aatest.clocksync.edges import joint_slope_range
from aatest.clocksync.freeze_pulse import SyncedStep, clock_relation, synchronise
from aatest.clocksync.phase_trend import (
    PhaseTrend,
    combined_drift,
    edges_fix_drift,
    step_phase_trend,
    trend_slope_range,
    trends_of,
)
from aatest.clocksync.relation import ClockRelation
from aatest.engine.steps import PlannedStep
from aatest.plugins.analysis.sync_summary import Related
from aatest.plugins.analysis.sync_watches import (
    SYNC_CHANNELS,
    SyncedWatch,
    synchronised_of,
    watch_synced,
)
from aatest.plugins.analysis.synced_steps import SyncedSteps
from aatest.recording.dataset import Dataset, LazySteps, StepData

#: the synced watch that measures each sine step's phase trend during the sync pass
_TREND_WATCH = "sync.phase_trend"
#: the table's record of the motion a trend is measured against
_MOTION = tuple(f"{a}_{q}" for a in ("inner", "outer") for q in ("position_deg", "accel_dps2"))


def _is_sine(step: PlannedStep) -> bool:
    return step.kind == "sine"


def watch_trends(data: Dataset) -> None:
    """Have the sync pass measure the sine steps' phase trends from the decode and resampling
    it makes anyway (the FRF reads the same volts), so a recording is not decoded again.

    Only the moving axis' motion is asked of each step: the trend reads no other
    (:func:`~aatest.clocksync.phase_trend.step_phase_trend`), and the other axis' encoder
    position, delta-coded, cost ≈ 1 ms of decoding a step for nothing.
    """
    sensors = [s.channel for s in data.sensors]

    def channels(step: PlannedStep) -> dict[str, list[str]]:
        return {"table": list(_moving_motion(step)), "daq": sensors}

    watch_synced(data, _TREND_WATCH, SyncedWatch(channels, _is_sine, needed_trend))


def _moving_motion(step: PlannedStep) -> tuple[str, ...]:
    """The table's record of a step's motion on its moving axis (what the trend reads)."""
    axis = step.axis if step.axis in ("inner", "outer") else "inner"
    return tuple(name for name in _MOTION if name.startswith(f"{axis}_"))


def _trend_unused(relation: ClockRelation, step: PlannedStep) -> bool:
    """Whether :func:`narrowed_by_trend` reads no trend once this step's relation is known:
    it refits only when no step is latched and no step's edges fix the drift themselves."""
    return relation.latched or edges_fix_drift(relation, 1.0 / step.sample_rate_hz)


def needed_trend(synced: SyncedStep) -> PhaseTrend | None:
    """The step's phase trend (:func:`step_phase_trend`), or None where no refit will read it.

    Why: with latch times (or edges that fix the drift) the trend is never used, and
    measuring it was ≈ 15 % of the stepped sine's analysis CPU (two batched segment fits of
    three quarters of every record), for nothing. :func:`narrowed_by_trend` reads the trends
    only when every step needs one, so leaving them out changes no result.
    """
    if _trend_unused(synced.relation, synced.step):
        return None
    return step_phase_trend(synced)


def _trends(data: Dataset, synced: SyncedSteps, related: Sequence[SyncedStep | Related]
            ) -> list[PhaseTrend]:
    """The phase trend of every sine step (synchronised with its edge relation): made by the
    sync pass (:func:`watch_trends`), else from the sensors' volts and the table's motion."""
    if synced._kept is not None:  # steps in memory: already synchronised
        return list(trends_of(s for s in related if isinstance(s, SyncedStep)).values())
    view = synced.where(_is_sine).only(_MOTION, [s.channel for s in data.sensors])
    return [t for t in view.reduced(_TREND_WATCH, needed_trend) if t is not None]


def narrowed_by_trend(data: Dataset, synced: SyncedSteps,
                       related: list[SyncedStep | Related]) -> list[SyncedStep | Related]:
    """Without latch times: every step refitted inside the drifts the sine steps' phase trend
    allows (:mod:`aatest.clocksync.phase_trend`), where the edges only bound it (no step's
    edges cross two table samples, :func:`edges_fix_drift`).

    One crystal drives the DAQ through every step, so the steps' trends are pooled and each
    step's relation is refitted with its slope inside that range (its offset from its own
    edges and trigger, as before). Results the sync pass already made with the edge relation
    (synced watches) are dropped, so the analyses recompute them on the refitted steps.
    """
    rel = [s.relation for s in related]
    if not rel or any(_trend_unused(s.relation, s.step) for s in related):
        return related
    pooled = combined_drift(_trends(data, synced, related))
    narrowed = None if pooled is None else trend_slope_range(pooled, joint_slope_range(rel))
    if narrowed is None:
        return related
    out: list[SyncedStep | Related] = []
    for i, entry in zip(synced._indices, related, strict=True):
        raw = data.steps[i] if synced._kept is not None else _sync_channels(data, i)
        relation = clock_relation(raw, narrowed)
        relation = replace(relation, phase_trend=_inside(relation.slope_range, narrowed))
        synced.relations[i] = relation
        if synced._kept is not None:
            synced._kept[i] = synchronise(raw, relation)
            out.append(synced._kept[i])
            continue
        kept = synchronised_of(data.steps, i)
        if kept is not None:  # made with the edge relation: recomputed on the refitted one
            kept.results.clear()
        out.append(Related(entry.step, relation))
    return out


def _inside(inner: tuple[float, float] | None, outer: tuple[float, float]) -> bool:
    """Whether a step's refitted slopes lie inside the trend's (a streamed record, or one whose
    own edges exclude the trend's range, keeps its own)."""
    tol = 1e-12  # slopes are ~1: rounding of the intersection
    return inner is not None and inner[0] >= outer[0] - tol and inner[1] <= outer[1] + tol


def _sync_channels(data: Dataset, index: int) -> StepData:
    """Step ``index`` of a recording with its sync channels only."""
    steps = data.steps
    assert isinstance(steps, LazySteps)  # only a recording's steps are not kept
    return steps.partial(index, SYNC_CHANNELS)
