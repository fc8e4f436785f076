"""The ``sync`` analysis: the clock relation of every step, summarised for results.json.

Memory: a recording's steps are decoded when read (:class:`~aatest.recording.dataset.LazySteps`),
so the synchronised steps handed to the other analyses are a :class:`SyncedSteps` view that
synchronises a step when it is read and keeps nothing: an analysis iterating them holds one
step at a time, whatever the number of steps. Steps already in memory (a simulated or test
dataset) are synchronised once and kept, as before.

Time: the sync pass is the first to decode every recorded step, so it decodes each once for
all: analyses that will read the steps register small per-step reductions before it runs
(:func:`watch_synced`: the FRF points, the transfer function's cross-correlations; and on the
raw steps the uncertainty evidence, :meth:`LazySteps.watch`), which it makes from the same
decode and synchronisation (:func:`relations`; optionally several steps at a time).
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, ClassVar, overload
from weakref import WeakKeyDictionary

import numpy as np

from aatest.clocksync.edges import joint_slope_range
from aatest.clocksync.freeze_pulse import (
    ClockRelation,
    SyncedStep,
    clock_relation,
    synchronise,
)
from aatest.clocksync.phase_trend import (
    PhaseTrend,
    combined_drift,
    edges_fix_drift,
    step_phase_trend,
    trend_slope_range,
    trends_of,
)
from aatest.clocksync.streamed import is_partial, streamed_relation, synchronise_streamed
from aatest.engine.forked import parallel_map
from aatest.engine.interfaces import AnalysisContext, AnalysisOutput, NoOptions
from aatest.engine.requirements import Requirement
from aatest.engine.steps import PlannedStep
from aatest.plugins.analysis import needs
from aatest.presentation.figures import new_figure, to_svg
from aatest.recording.dataset import Dataset, LazySteps, StepData, StepWatch
from aatest.results.sync import SyncResult

#: the channels a clock relation reads (besides the time stamps)
_SYNC_CHANNELS = {"table": ("sync_pulse", "fp_latch_s"), "daq": ("sync_pulse", "trigger")}


#: a watched result not (or no longer) there
_MISSING = object()


@dataclass(frozen=True)
class SyncedWatch:
    """A small reduction of a synchronised step, made while the sync pass decodes the step.

    Why: the sync pass decodes every recorded step to fit its clock relation; an analysis that
    will read the same steps later (the FRF points, the transfer function's cross-correlation)
    registers a watch with :func:`watch_synced` before the pass, and reads the result with
    :meth:`SyncedSteps.reduced` instead of decoding and synchronising each step again. The
    pass then decodes the union of the channels once, synchronises it once, and feeds every
    watch the same synchronised step (each channel decoded and resampled exactly as a decode
    of only that watch's channels would). Results must be small: one is kept per step.

    Parameters
    ----------
    channels
        The table and DAQ channels the reduction reads, by source (``"table"``/``"daq"``).
    applies
        Whether the reduction is wanted for a planned step.
    reduce
        The reduction of the synchronised step.
    """

    channels: Mapping[str, Collection[str]]
    applies: Callable[[PlannedStep], bool]
    reduce: Callable[[SyncedStep], Any]


@dataclass(frozen=True)
class _Synchronised:
    """What the sync pass keeps of a watched step: its clock relation and the watches'
    results by name (each taken once, by :meth:`SyncedSteps.reduced`)."""

    relation: ClockRelation
    results: dict[str, Any] = field(default_factory=dict)


class _Watches:
    """The synced watches of one recording: one :class:`StepWatch` on its lazy steps that
    fits the clock relation, synchronises once and runs every watch due on the step."""

    name: ClassVar[str] = "sync.synchronised"

    def __init__(self) -> None:
        self.watches: dict[str, SyncedWatch] = {}

    def _due(self, step: PlannedStep) -> list[tuple[str, SyncedWatch]]:
        return [(n, w) for n, w in self.watches.items() if step.recorded and w.applies(step)]

    def channels(self, step: PlannedStep) -> dict[str, list[str]]:
        due = [w for _, w in self._due(step)]
        return {source: list(dict.fromkeys([*_SYNC_CHANNELS[source], *(
            name for w in due for name in w.channels.get(source, ()))]))
            for source in ("table", "daq")}

    def applies(self, step: PlannedStep) -> bool:
        return bool(self._due(step))

    def reduce(self, raw: StepData) -> _Synchronised:
        relation = clock_relation(raw)
        synced = synchronise(raw, relation)
        done = _Synchronised(relation)
        for name, watch in self._due(raw.step):
            try:
                done.results[name] = watch.reduce(synced)
            except Exception:  # noqa: BLE001 - its owner recomputes the step, meets the error
                continue
        return done


#: the synced watches of each recording's lazy steps (gone with the steps)
_REGISTERED: WeakKeyDictionary[LazySteps, _Watches] = WeakKeyDictionary()


def watch_synced(data: Dataset, name: str, watch: SyncedWatch) -> None:
    """Have the sync pass run ``watch`` on every step it applies to (see :class:`SyncedWatch`).

    Only a recording's lazy steps are watched (steps in memory are synchronised once and kept
    anyway); register before the sync pass runs, e.g. from an analysis' ``watch_steps``.
    """
    steps = data.steps
    if not isinstance(steps, LazySteps):
        return
    if steps not in _REGISTERED:
        watches = _REGISTERED[steps] = _Watches()
        steps.watch(_Watches.name, StepWatch(watches.channels, watches.applies, watches.reduce))
    _REGISTERED[steps].watches.setdefault(name, watch)


def _synchronised(steps: Sequence[StepData], index: int) -> _Synchronised | None:
    """What the sync pass kept of step ``index`` of a recording's lazy steps, if anything."""
    if not isinstance(steps, LazySteps):
        return None
    try:
        found: _Synchronised = steps.watched(_Watches.name, index)
    except KeyError:
        return None
    return found


class SyncedSteps(Sequence[SyncedStep]):
    """Recorded steps synchronised when read; ``planned`` and :meth:`where` decode nothing.

    Parameters
    ----------
    steps
        The dataset's steps (any sequence; a :class:`LazySteps` decodes a step when read).
    indices
        Which of ``steps`` this view holds, in order.
    planned
        The planned step of each held step.
    keep
        Synchronise each step once and keep it (steps already in memory), else on every read.
    """

    def __init__(self, steps: Sequence[StepData], indices: Sequence[int],
                 planned: Sequence[PlannedStep], keep: bool) -> None:
        self._steps, self._indices, self.planned = steps, tuple(indices), tuple(planned)
        self._kept: dict[int, SyncedStep] | None = {} if keep else None
        #: clock relations already fitted (by the sync pass), reused when a step is read
        self.relations: dict[int, ClockRelation] = {}
        #: decode (and resample) only these channels by source; None: all of them
        self._channels: Mapping[str, tuple[str, ...]] | None = None

    @classmethod
    def of(cls, data: Dataset) -> SyncedSteps:
        """Every recorded step of ``data``."""
        pairs = [(i, p) for i, p in enumerate(data.planned) if p.recorded]
        return cls(data.steps, [i for i, _ in pairs], [p for _, p in pairs],
                   keep=not isinstance(data.steps, LazySteps))

    def where(self, keep: Callable[[PlannedStep], bool]) -> SyncedSteps:
        """The steps whose planned step passes ``keep`` (a view sharing this one's cache)."""
        chosen = [k for k, p in enumerate(self.planned) if keep(p)]
        view = SyncedSteps(self._steps, [self._indices[k] for k in chosen],
                           [self.planned[k] for k in chosen], keep=False)
        view._kept, view.relations, view._channels = self._kept, self.relations, self._channels
        return view

    def only(self, table: Collection[str], daq: Collection[str]) -> SyncedSteps:
        """The same steps with only these table and DAQ channels (the time stamps always).

        Why: an analysis reading one sensor and the table's acceleration of every step (the
        transfer function's cross-correlation) then decodes and resamples those channels,
        not the whole logs — the same values, a fraction of the work. A channel a step did not
        log is simply absent. Steps already in memory are returned whole.
        """
        if self._kept is not None or not isinstance(self._steps, LazySteps):
            return self
        view = SyncedSteps(self._steps, self._indices, self.planned, keep=False)
        view.relations = self.relations
        view._channels = {"table": tuple(table), "daq": tuple(daq)}
        return view

    def __len__(self) -> int:
        return len(self._indices)

    @overload
    def __getitem__(self, index: int) -> SyncedStep: ...

    @overload
    def __getitem__(self, index: slice) -> Sequence[SyncedStep]: ...

    def __getitem__(self, index: int | slice) -> SyncedStep | Sequence[SyncedStep]:
        if isinstance(index, slice):
            return [self[k] for k in range(*index.indices(len(self)))]
        i = self._indices[index]
        if self._kept is None and _is_long(self._steps, i):
            return _long_synced(self._steps, i, self.relations.get(i))
        if self._kept is None:
            return synchronise(self._step(i), self.relations.get(i))
        if i not in self._kept:
            self._kept[i] = synchronise(self._steps[i], self.relations.get(i))
        return self._kept[i]

    def __iter__(self) -> Iterator[SyncedStep]:
        return (self[k] for k in range(len(self)))

    def reduced(self, name: str, reduce: Callable[[SyncedStep], Any]) -> list[Any]:
        """``reduce`` of every held step, in order: the result of the synced watch ``name``
        where the sync pass made it (taken: a second call computes it anew), else computed
        now from the step (decoded and synchronised as it is read).

        ``reduce`` must be the watch's reduction, so that both give the same values.
        """
        out: list[Any] = []
        for k, i in enumerate(self._indices):
            kept = _synchronised(self._steps, i)
            found = _MISSING if kept is None else kept.results.pop(name, _MISSING)
            out.append(reduce(self[k]) if found is _MISSING else found)
        return out

    def _step(self, i: int) -> StepData:
        """Step ``i`` of the dataset, partly decoded when this view names its channels (with
        the sync channels when its clock relation is still to be fitted)."""
        if self._channels is None:
            return self._steps[i]
        steps = self._steps
        assert isinstance(steps, LazySteps)  # what only() checked
        wanted = {source: {*names, *(() if i in self.relations else _SYNC_CHANNELS[source])}
                  for source, names in self._channels.items()}
        return steps.partial(i, wanted)


def _is_long(steps: Sequence[StepData], index: int) -> bool:
    """Whether recorded step ``index`` of a recording is a long record whose table logged
    only its head (:func:`~aatest.clocksync.streamed.is_partial`; nothing is decoded)."""
    if not isinstance(steps, LazySteps):
        return False
    counts = steps[index]
    return is_partial(counts.step, counts.samples("table"), counts.samples("daq"))


def _long_synced(steps: Sequence[StepData], index: int,
                 relation: ClockRelation | None) -> SyncedStep:
    """A long record synchronised: its table log whole (the head), its DAQ log piece by piece."""
    assert isinstance(steps, LazySteps)  # what _is_long checked
    step = steps[index]
    return synchronise_streamed(step.step, step.table,
                                lambda channels: steps.pieces(index, "daq", channels), relation)


def _relation_of(steps: LazySteps, index: int) -> ClockRelation:
    """The clock relation of recorded step ``index``, its synced watches fed on the way."""
    if _is_long(steps, index):  # the DAQ record read piece by piece, never whole
        step = steps[index]
        return streamed_relation(step.step, step.table,
                                 lambda channels: steps.pieces(index, "daq", channels))
    part = steps.partial(index, _SYNC_CHANNELS)  # synced watches ride along
    kept = _synchronised(steps, index)
    return kept.relation if kept is not None else clock_relation(part)


def relations(steps: LazySteps, indices: Sequence[int],
              workers: int | None = None) -> list[tuple[int, ClockRelation]]:
    """``(index, clock relation)`` of each of ``indices``, in their order, on ``workers``
    forked processes (default: one per CPU; see :func:`aatest.engine.forked.fork_workers`
    for when it is one, this process's own loop).

    Why processes: the pass is most of the analysis phase (stepped sine: decoding, clock fit,
    resampling and the watched FRF and cross-correlation reductions of 136 steps) and holds
    the GIL for much of it; measured on the 2-core machine, two threads gained ≤ 5 %, two
    forked workers ≈ 45 % (``bench/end_to_end.py``). Each step's relation and watched results
    depend only on that step, so they are the same whatever the worker; the workers hand the
    watched results back (:meth:`LazySteps.kept`) and this process keeps them. The error of
    the first failing step in order is the one raised (:func:`parallel_map`).
    """
    made = parallel_map(lambda i: (_relation_of(steps, i), steps.kept(i)), indices, workers)
    for index, (_, kept) in zip(indices, made, strict=True):
        steps.keep(index, kept)
    return [(index, relation) for index, (relation, _) in zip(indices, made, strict=True)]


#: the synced watch that measures each sine step's phase trend during the sync pass
_TREND_WATCH = "sync.phase_trend"
#: the table's record of the motion a trend is measured against
_MOTION = tuple(f"{a}_{q}" for a in ("inner", "outer") for q in ("position_deg", "accel_dps2"))


def _is_sine(step: PlannedStep) -> bool:
    return step.kind == "sine"


def _watch_trends(data: Dataset) -> None:
    """Have the sync pass measure the sine steps' phase trends from the decode and resampling
    it makes anyway (the FRF reads the same volts), so a recording is not decoded again."""
    watch_synced(data, _TREND_WATCH, SyncedWatch(
        {"table": _MOTION, "daq": [s.channel for s in data.sensors]}, _is_sine,
        step_phase_trend))


def _trends(data: Dataset, synced: SyncedSteps, related: Sequence[SyncedStep | _Related]
            ) -> list[PhaseTrend]:
    """The phase trend of every sine step (synchronised with its edge relation): made by the
    sync pass (:func:`_watch_trends`), else from the sensors' volts and the table's motion."""
    if synced._kept is not None:  # steps in memory: already synchronised
        return list(trends_of(s for s in related if isinstance(s, SyncedStep)).values())
    view = synced.where(_is_sine).only(_MOTION, [s.channel for s in data.sensors])
    return [t for t in view.reduced(_TREND_WATCH, step_phase_trend) if t is not None]


def _narrowed_by_trend(data: Dataset, synced: SyncedSteps,
                       related: list[SyncedStep | _Related]) -> list[SyncedStep | _Related]:
    """Without latch times: every step refitted inside the drifts the sine steps' phase trend
    allows (:mod:`aatest.clocksync.phase_trend`), where the edges only bound it (no step's
    edges cross two table samples, :func:`edges_fix_drift`).

    One crystal drives the DAQ through every step, so the steps' trends are pooled and each
    step's relation is refitted with its slope inside that range (its offset from its own
    edges and trigger, as before). Results the sync pass already made with the edge relation
    (synced watches) are dropped, so the analyses recompute them on the refitted steps.
    """
    rel = [s.relation for s in related]
    if not rel or any(r.latched for r in rel) or any(
            edges_fix_drift(s.relation, 1.0 / s.step.sample_rate_hz) for s in related):
        return related
    pooled = combined_drift(_trends(data, synced, related))
    narrowed = None if pooled is None else trend_slope_range(pooled, joint_slope_range(rel))
    if narrowed is None:
        return related
    out: list[SyncedStep | _Related] = []
    for i, entry in zip(synced._indices, related, strict=True):
        raw = data.steps[i] if synced._kept is not None else _sync_channels(data, i)
        relation = clock_relation(raw, narrowed)
        relation = replace(relation, phase_trend=_inside(relation.slope_range, narrowed))
        synced.relations[i] = relation
        if synced._kept is not None:
            synced._kept[i] = synchronise(raw, relation)
            out.append(synced._kept[i])
            continue
        kept = _synchronised(data.steps, i)
        if kept is not None:  # made with the edge relation: recomputed on the refitted one
            kept.results.clear()
        out.append(_Related(entry.step, relation))
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
    return steps.partial(index, _SYNC_CHANNELS)


@dataclass(frozen=True)
class SyncOutput(AnalysisOutput[SyncResult]):
    """The sync result plus the synchronised steps themselves (not written to results.json);
    every analysis that ``requires`` sync reads them from ``context.upstream["sync"]``."""

    steps: Sequence[SyncedStep] = ()


@dataclass(frozen=True)
class _Related:
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


def summarise(steps: Sequence[SyncedStep | _Related]) -> SyncResult:
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


def sync_figure(steps: Sequence[SyncedStep | _Related]) -> str:
    """Drift and clock-relation residual of every step (one crystal: a flat drift line)."""
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
    #: what the plan must hold (checked by ``validate``; aatest.engine.requirements)
    requirements: ClassVar[tuple[Requirement, ...]] = needs.SYNC
    #: the acceptance quantities it produces (judged when it is listed)
    judges: ClassVar[tuple[str, ...]] = ()
    Options: ClassVar[type[NoOptions]] = NoOptions

    @staticmethod
    def check_step(step: StepData) -> None:
        """The run's check of one step as it is recorded: its clock relation can be fitted
        (pulses, trigger and time stamps only), else :class:`AnalysisError`."""
        clock_relation(step)
    Result: ClassVar[type[SyncResult]] = SyncResult

    def applies_to(self, data: Dataset) -> bool:
        return any(p.recorded for p in data.planned)

    def run(self, data: Dataset, context: AnalysisContext) -> SyncOutput:
        synced = SyncedSteps.of(data)
        if synced._kept is not None:  # steps in memory: synchronise them all now, and keep
            related: list[SyncedStep | _Related] = list(synced)
        else:  # one step at a time: only its clock relation stays
            steps = data.steps
            assert isinstance(steps, LazySteps)  # what keep=False means
            _watch_trends(data)
            synced.relations.update(relations(steps, synced._indices))
            related = [_Related(p, synced.relations[i])
                       for i, p in zip(synced._indices, synced.planned, strict=True)]
        related = _narrowed_by_trend(data, synced, related)
        return SyncOutput(result=summarise(related), figures={"sync": sync_figure(related)},
                          steps=synced)
