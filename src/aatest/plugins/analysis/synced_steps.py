"""Recorded steps synchronised when read, and the sync pass that fits their clock relations.

Memory: a recording's steps are decoded when read (:class:`~aatest.recording.dataset.LazySteps`),
so the synchronised steps handed to the other analyses are a :class:`SyncedSteps` view that
synchronises a step when it is read and keeps nothing. Time: :func:`relations` fits every
step's clock relation from one decode, feeding the synced watches
(:mod:`aatest.plugins.analysis.sync_watches`) on the way; optionally several steps at a time.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Collection, Iterator, Mapping, Sequence
from typing import Any, overload
from weakref import WeakKeyDictionary

from aatest.clocksync.freeze_pulse import ClockRelation, SyncedStep, clock_relation, synchronise
from aatest.clocksync.streamed import is_partial, streamed_relation, synchronise_streamed
from aatest.engine.steps import PlannedStep
from aatest.parallel.forked import parallel_map
from aatest.plugins.analysis.sync_watches import SYNC_CHANNELS, WATCHES_NAME, synchronised_of
from aatest.recording.dataset import Dataset, LazySteps, StepData

#: a watched result not (or no longer) there
_MISSING = object()
#: what one step's share of the sync pass makes: its clock relation and watched results
Attempt = tuple[ClockRelation, dict[str, Any]]
#: attempts made elsewhere of the same recorded data (:func:`offer`), by lazy steps and index
_OFFERED: WeakKeyDictionary[LazySteps, dict[int, Attempt]] = WeakKeyDictionary()

log = logging.getLogger("aatest.analysis")


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
        if self._kept is None and is_long_record(self._steps, i):
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
            kept = synchronised_of(self._steps, i)
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
        wanted = {source: {*names, *(() if i in self.relations else SYNC_CHANNELS[source])}
                  for source, names in self._channels.items()}
        return steps.partial(i, wanted)


def is_long_record(steps: Sequence[StepData], index: int) -> bool:
    """Whether recorded step ``index`` of a recording is a long record whose table logged
    only its head (:func:`~aatest.clocksync.streamed.is_partial`; nothing is decoded)."""
    if not isinstance(steps, LazySteps):
        return False
    counts = steps[index]
    return is_partial(counts.step, counts.samples("table"), counts.samples("daq"))


def _long_synced(steps: Sequence[StepData], index: int,
                 relation: ClockRelation | None) -> SyncedStep:
    """A long record synchronised: its table log whole (the head), its DAQ log piece by piece."""
    assert isinstance(steps, LazySteps)  # what is_long_record checked
    step = steps[index]
    return synchronise_streamed(step.step, step.table,
                                lambda channels: steps.pieces(index, "daq", channels), relation)


def _relation_of(steps: LazySteps, index: int) -> ClockRelation:
    """The clock relation of recorded step ``index``, its synced watches fed on the way."""
    if is_long_record(steps, index):  # the DAQ record read piece by piece, never whole
        step = steps[index]
        return streamed_relation(step.step, step.table,
                                 lambda channels: steps.pieces(index, "daq", channels))
    part = steps.partial(index, SYNC_CHANNELS)  # synced watches ride along
    kept = synchronised_of(steps, index)
    return kept.relation if kept is not None else clock_relation(part)


def relations(steps: LazySteps, indices: Sequence[int],
              workers: int | None = None) -> list[tuple[int, ClockRelation]]:
    """``(index, clock relation)`` of each of ``indices``, in their order, on ``workers``
    forked processes (default: one per CPU; see :func:`aatest.parallel.forked.fork_workers`
    for when it is one, this process's own loop).

    Why processes: the pass is most of the analysis phase (stepped sine: decoding, clock fit,
    resampling and the watched FRF and cross-correlation reductions of 136 steps) and holds
    the GIL for much of it; measured on the 2-core machine, two threads gained ≤ 5 %, two
    forked workers ≈ 45 % (``bench/end_to_end.py``). Each step's relation and watched results
    depend only on that step, so they are the same whatever the worker; the workers hand the
    watched results back (:meth:`LazySteps.kept`) and this process keeps them.

    Why the steps go to the workers in batches of one frequency (:func:`_batches`): a
    watched FRF point's segment fit is a projector (the fundamental's rows of the fit's normal
    equations) that depends only on the frequency and the record length, computed once per
    worker and kept
    (:func:`aatest.plugins.analysis.frf._segment_projector`); a stepped sine repeats each
    frequency in every group, so step by step both workers computed nearly every one of
    them, batch by batch one worker does. The error of the first failing step in order is
    the one raised, here, with its own traceback: a step that failed in a worker is computed
    again in this process.

    A step :func:`offer` was given (``aatest run`` made it while recording, of the same bytes:
    :mod:`aatest.early.analysis`) is taken as it is, not computed again.
    """
    offered = _OFFERED.pop(steps, {})
    todo = [i for i in indices if i not in offered]
    batches = _batches(steps, todo)
    made = parallel_map(lambda batch: [attempt(steps, i) for i in batch], batches, workers)
    attempts: dict[int, Attempt | None] = {
        i: found for batch, out in zip(batches, made, strict=True)
        for i, found in zip(batch, out, strict=True)}
    attempts |= {i: offered[i] for i in indices if i in offered}
    log.debug("sync pass: %d of %d steps taken as analysed while the run recorded",
              len(indices) - len(todo), len(indices))
    related: list[tuple[int, ClockRelation]] = []
    for index in indices:
        found = attempts[index]
        relation, kept = found if found is not None else (_relation_of(steps, index),
                                                          steps.kept(index))
        steps.keep(index, kept)
        related.append((index, relation))
    return related


def offer(steps: LazySteps, index: int, found: Attempt) -> None:
    """Hand :func:`relations` step ``index``'s :func:`attempt`, made elsewhere of the same
    recorded bytes (the caller checks that: :mod:`aatest.recording.step_chunks`) with the same
    watches registered; the pass then takes it instead of decoding the step. Taken once."""
    _OFFERED.setdefault(steps, {})[index] = found


def attempt(steps: LazySteps, index: int) -> Attempt | None:
    """The clock relation and watched results of step ``index``, or None when it raised
    (the caller computes it again and meets the error with its traceback)."""
    try:
        return _relation_of(steps, index), steps.kept(index)
    except Exception:  # noqa: BLE001 - raised again by the caller's own call, in order
        return None


def attempt_result(found: Any, name: str) -> Any:
    """The synced watch ``name``'s result in a step's :func:`attempt` (made elsewhere: the
    child of :mod:`aatest.early.analysis` keeps them), or None when it was not made."""
    kept_by_name = found[1] if isinstance(found, tuple) and found[1:] else None
    if not isinstance(kept_by_name, Mapping):
        return None
    kept = kept_by_name.get(WATCHES_NAME)
    results = getattr(kept, "results", None)
    return results.get(name) if isinstance(results, Mapping) else None


def _batches(steps: LazySteps, indices: Sequence[int]) -> list[list[int]]:
    """``indices`` cut into the pass's work items: the sine steps of one frequency and rate
    together (their FRF fits share one design), every other step alone. The largest items
    go first (then in the order of their first step), so the workers finish together: the
    last items handed out are the shortest."""
    items: dict[Any, list[int]] = {}
    for index in indices:
        step = steps.planned[index]
        key = ((step.frequency_hz, step.sample_rate_hz) if step.kind == "sine"
               and step.frequency_hz else ("step", index))
        items.setdefault(key, []).append(index)
    return sorted(items.values(), key=len, reverse=True)
