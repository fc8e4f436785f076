"""Synced watches: small per-step reductions made while the sync pass decodes each step.

Why a module of its own: the sync pass (:mod:`aatest.plugins.analysis.synced_steps`) is the
first to decode every recorded step, so analyses that will read the same steps register their
reductions here (:func:`watch_synced`) and the pass feeds them from its one decode and
synchronisation; :func:`synchronised_of` hands back what it kept of a step.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar
from weakref import WeakKeyDictionary

from aatest.clocksync.freeze_pulse import (
    ClockRelation,
    SyncedStep,
    fit_and_synchronise,
    synchronise,
)
from aatest.engine.steps import PlannedStep
from aatest.plugins.analysis.step_spectra import shared
from aatest.recording.dataset import Dataset, LazySteps, StepData, StepWatch

#: the channels a clock relation reads (besides the time stamps)
SYNC_CHANNELS = {"table": ("sync_pulse", "fp_latch_s"), "daq": ("sync_pulse", "trigger")}



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
        The table and DAQ channels the reduction reads, by source (``"table"``/``"daq"``);
        or a function giving them for a planned step (a reduction that reads only the
        moving axis' channels: the other axis' are then not decoded).
    applies
        Whether the reduction is wanted for a planned step.
    reduce
        The reduction of the synchronised step.
    """

    channels: Mapping[str, Collection[str]] | Callable[[PlannedStep], Mapping[str, Collection[str]]]
    applies: Callable[[PlannedStep], bool]
    reduce: Callable[[SyncedStep], Any]

    def channels_of(self, step: PlannedStep) -> Mapping[str, Collection[str]]:
        """The channels the reduction reads of ``step``, by source."""
        return self.channels(step) if callable(self.channels) else self.channels


@dataclass(frozen=True)
class Synchronised:
    """What the sync pass keeps of a watched step: its clock relation and the watches'
    results by name (each taken once, by :meth:`SyncedSteps.reduced`)."""

    relation: ClockRelation
    results: dict[str, Any] = field(default_factory=dict)


#: the name the synced watches' one step watch is registered under (the key of their
#: :class:`Synchronised` in a step's kept results)
WATCHES_NAME = "sync.synchronised"


class _Watches:
    """The synced watches of one recording: one :class:`StepWatch` on its lazy steps that
    fits the clock relation, synchronises once and runs every watch due on the step."""

    name: ClassVar[str] = WATCHES_NAME

    def __init__(self) -> None:
        self.watches: dict[str, SyncedWatch] = {}
        #: clock relations already fitted on a step's data, by step id (:func:`known_relation`)
        self.known: dict[str, ClockRelation] = {}

    def _due(self, step: PlannedStep) -> list[tuple[str, SyncedWatch]]:
        return [(n, w) for n, w in self.watches.items() if step.recorded and w.applies(step)]

    def channels(self, step: PlannedStep) -> dict[str, list[str]]:
        due = [w.channels_of(step) for _, w in self._due(step)]
        return {source: list(dict.fromkeys([*SYNC_CHANNELS[source], *(
            name for channels in due for name in channels.get(source, ()))]))
            for source in ("table", "daq")}

    def applies(self, step: PlannedStep) -> bool:
        return bool(self._due(step))

    def reduce(self, raw: StepData) -> Synchronised:
        known = self.known.pop(raw.step.id, None)
        synced = fit_and_synchronise(raw) if known is None else synchronise(raw, known)
        done = Synchronised(synced.relation)
        with shared():  # the watches read the same records: each transformed once
            for name, watch in self._due(raw.step):
                try:
                    done.results[name] = watch.reduce(synced)
                except Exception:  # noqa: BLE001 - its owner recomputes the step, meets it
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


def known_relation(data: Dataset, step_id: str, relation: ClockRelation) -> None:
    """Have the synced watches synchronise step ``step_id`` with ``relation`` instead of
    fitting it: the :func:`~aatest.clocksync.freeze_pulse.clock_relation` of the very arrays
    they will read, fitted elsewhere (the run-time check, :mod:`aatest.early.child`), so the
    same relation and synchronised step (``synchronise`` with the relation is
    ``fit_and_synchronise``, its fit skipped). Used once; nothing when no watch is
    registered on ``data``'s steps."""
    watches = _REGISTERED.get(data.steps) if isinstance(data.steps, LazySteps) else None
    if watches is not None:
        watches.known[step_id] = relation


def synchronised_of(steps: Sequence[StepData], index: int) -> Synchronised | None:
    """What the sync pass kept of step ``index`` of a recording's lazy steps, if anything."""
    if not isinstance(steps, LazySteps):
        return None
    try:
        found: Synchronised = steps.watched(_Watches.name, index)
    except KeyError:
        return None
    return found
