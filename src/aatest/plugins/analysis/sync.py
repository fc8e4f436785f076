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

The parts, one job each (their public names are importable from here too): the synced watches
(:mod:`~aatest.plugins.analysis.sync_watches`), the synchronised view and the pass
(:mod:`~aatest.plugins.analysis.synced_steps`), the latch-less refit by the sine steps' phase
trend (:mod:`~aatest.plugins.analysis.sync_trend`) and the summary with its figure
(:mod:`~aatest.plugins.analysis.sync_summary`); this module runs them in order.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

from aatest.clocksync.freeze_pulse import ClockRelation, SyncedStep, clock_relation
from aatest.engine.interfaces import AnalysisContext, AnalysisOutput, NoOptions
from aatest.engine.requirements import Requirement
from aatest.plugins.analysis import needs
from aatest.plugins.analysis.sync_summary import (
    Related,
    joint_drift,
    summarise,
    sync_figure,
    sync_plot,
    sync_plotted,
)
from aatest.plugins.analysis.sync_trend import narrowed_by_trend, watch_trends
from aatest.plugins.analysis.sync_watches import (
    SYNC_CHANNELS,
    SyncedWatch,
    known_relation,
    watch_synced,
)
from aatest.plugins.analysis.synced_steps import SyncedSteps, attempt, offer, relations
from aatest.presentation.figures import DrawnFigures, drawn
from aatest.recording.dataset import Dataset, LazySteps, StepData
from aatest.results.sync import SyncResult

#: the channels a clock relation reads (the name the tests and earlier callers import)
_SYNC_CHANNELS = SYNC_CHANNELS

__all__ = [
    "SyncAnalysis", "SyncOutput", "SyncedSteps", "SyncedWatch", "joint_drift", "relations",
    "summarise", "sync_figure", "watch_synced",
]


@dataclass(frozen=True)
class SyncOutput(AnalysisOutput[SyncResult]):
    """The sync result plus the synchronised steps themselves (not written to results.json);
    every analysis that ``requires`` sync reads them from ``context.upstream["sync"]``."""

    steps: Sequence[SyncedStep] = ()


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
    def check_step(step: StepData) -> ClockRelation:
        """The run's check of one step as it is recorded: its clock relation can be fitted
        (pulses, trigger and time stamps only), else :class:`AnalysisError`. Returns it
        (the early analysis takes it instead of fitting it again: :mod:`aatest.early`)."""
        return clock_relation(step)
    Result: ClassVar[type[SyncResult]] = SyncResult

    @staticmethod
    def early_step(data: Dataset, index: int) -> Any:
        """Step ``index``'s share of the sync pass (its clock relation and watched results),
        made while the run still records (:mod:`aatest.early.analysis`; the pass's
        watches are registered on ``data``), or None when it raised: the pass then computes
        the step itself and meets the error there."""
        steps = data.steps
        if not isinstance(steps, LazySteps):
            return None
        watch_trends(data)  # as run() registers it before the pass
        return attempt(steps, index)

    @staticmethod
    def known_relation(data: Dataset, step_id: str, relation: ClockRelation) -> None:
        """Have the pass's watches on ``data`` synchronise step ``step_id`` with ``relation``,
        the clock relation of the very arrays they will read, instead of fitting it
        (:func:`~aatest.plugins.analysis.sync_watches.known_relation`)."""
        known_relation(data, step_id, relation)

    @staticmethod
    def take_early(data: Dataset, index: int, found: Any) -> None:
        """Have the pass take :meth:`early_step`'s result for step ``index`` of ``data``,
        checked by the caller to be of the same recorded bytes and watches."""
        if isinstance(data.steps, LazySteps) and found is not None:
            offer(data.steps, index, found)

    def applies_to(self, data: Dataset) -> bool:
        return any(p.recorded for p in data.planned)

    def run(self, data: Dataset, context: AnalysisContext) -> SyncOutput:
        synced = SyncedSteps.of(data)
        if synced._kept is not None:  # steps in memory: synchronise them all now, and keep
            related: list[SyncedStep | Related] = list(synced)
        else:  # one step at a time: only its clock relation stays
            steps = data.steps
            assert isinstance(steps, LazySteps)  # what keep=False means
            watch_trends(data)
            synced.relations.update(relations(steps, synced._indices))
            related = [Related(p, synced.relations[i])
                       for i, p in zip(synced._indices, synced.planned, strict=True)]
        related = narrowed_by_trend(data, synced, related)
        # drawn aside while the other analyses and the report go on (a flat drift line)
        figure = drawn(sync_plot, *sync_plotted(related))
        return SyncOutput(result=summarise(related), figures=DrawnFigures({"sync": figure}),
                          steps=synced)
