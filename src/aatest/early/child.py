"""The child process of :mod:`aatest.early.analysis`: each step file it is sent,
analysed as the analysis pass will analyse that step of ``recording.mcap``.

It builds the plan-wide view the pass sees (the plan's recorded steps, the sensors and sample
rate of the run record every step file embeds), registers the pass's watches on it
(:func:`~aatest.engine.analysis.passes.register_watches`, with the procedure's analyses and
options) and calls each applicable analysis plugin's ``early_step(data, index)``; each step
is decoded from its step file only. BLAS runs on one thread, as in the pass, so the sums are
the same. Nothing it does can fail the run: a step that raised is sent back as None.
"""

from __future__ import annotations

import logging
import signal
import warnings
from collections import deque
from collections.abc import Mapping, Sequence
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any

from aatest.early.made import DRAIN, Made, Warned, context_digest
from aatest.engine.steps import PlannedStep
from aatest.recording.dataset import Dataset, LazySteps


def main(argv: Sequence[str]) -> None:
    """The child's entry (``argv``: the descriptors of its inbox and outbox pipes)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's: it reaps this one
    # outside a step's analyses (imports, reading its file): theirs are recorded per step
    # (_Child._analyse) and raised again where the pass takes the step
    warnings.simplefilter("ignore")
    logging.disable(logging.CRITICAL)
    inbox = Connection(int(argv[0]), writable=False)
    outbox = Connection(int(argv[1]), readable=False)
    try:
        serve(inbox, outbox)
    finally:
        inbox.close()
        outbox.close()


def serve(inbox: Connection, outbox: Connection) -> None:
    """The child's loop: analyse each step file named on ``inbox`` and send ``(step id, Made
    or None)`` on ``outbox``; end on ``None`` (after the step in flight: newly arrived
    messages are read before each step), on :data:`DRAIN` once every step sent before it
    is done, or when the parent is gone."""
    from threadpoolctl import threadpool_limits

    from aatest.engine import registry

    queue: deque[tuple[str, str]] = deque()
    draining = False
    # BLAS on one thread, as in the pass (run_analyses): the same sums in the same order
    with registry.pinned(), threadpool_limits(limits=1, user_api="blas"):
        child = _Child()
        while True:
            if (not queue and not draining) or inbox.poll():
                try:
                    message = inbox.recv()
                except (EOFError, OSError):
                    return
                if message is None:
                    return
                if message == DRAIN:
                    draining = True
                else:
                    queue.append(message)
                continue
            if not queue:  # drained
                return
            step_id, path = queue.popleft()
            try:
                outbox.send((step_id, child.analyse(step_id, Path(path))))
            except (OSError, ValueError):
                return


class _Child:
    """The plan-wide view the child analyses each step in (from the first step file)."""

    def __init__(self) -> None:
        self._base: Dataset | None = None
        self._context = ""
        self._index: dict[str, int] = {}

    def analyse(self, step_id: str, path: Path) -> Made | None:
        """Step ``step_id``'s ``early_step`` results, or None when anything failed."""
        try:
            return self._analyse(step_id, path)
        except Exception:  # noqa: BLE001 - the pass computes the step and meets the error
            return None

    def _analyse(self, step_id: str, path: Path) -> Made:
        from aatest.engine.analysis.passes import register_watches
        from aatest.recording import read_dataset
        from aatest.recording.step_chunks import step_digests

        digest = step_digests(path, only={step_id})[step_id]
        single = read_dataset(path)
        base = self._base or self._first(single)
        index = self._index[step_id]
        data = _one_step_view(base, single.steps, index)
        watched = register_watches(data, list(data.metadata.get("analysis", [])))
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")  # each one; the run's filters judge them again
            results = {p.name: p.cls.early_step(data, index) for p in watched.plugins
                       if callable(getattr(p.cls, "early_step", None))
                       and p.cls().applies_to(data)}
        warned = tuple(Warned(f"{w.category.__module__}.{w.category.__qualname__}",
                              str(w.message), w.filename, w.lineno) for w in caught)
        return Made(digest, self._context, results, warned)

    def _first(self, single: Dataset) -> Dataset:
        """The plan's recorded steps, sensors and sample rate, as the recording will state
        them (its run record, as every step file embeds it)."""
        meta = single.metadata
        planned = [p for p in (PlannedStep.model_validate(e) for e in meta.get("plan") or [])
                   if p.recorded]
        rate = meta.get("sample_rate_hz") or (planned[0].sample_rate_hz if planned else
                                              single.sample_rate_hz)
        steps = LazySteps(planned, _no_log, [{} for _ in planned])
        self._base = Dataset(single.procedure, float(rate), single.sensors, steps,
                             single.source, meta)
        self._context = context_digest(self._base)
        self._index = {p.id: i for i, p in enumerate(planned)}
        return self._base


def _no_log(index: int, source: str, channels: Any) -> Any:
    raise LookupError(f"step {index} is not in this step file")


def _one_step_view(base: Dataset, single: Any, index: int) -> Dataset:
    """``base`` whose step ``index`` is the one step of a step file's lazy steps ``single``
    (fresh lazy steps: the watches registered on it see this step only)."""
    assert isinstance(single, LazySteps)
    counts: list[Mapping[str, int]] = [{} for _ in base.planned]
    counts[index] = {source: single[0].samples(source) for source in ("table", "daq")}
    steps = LazySteps(base.planned, lambda _i, source, channels: single.log(0, source, channels),
                      counts, lambda _i, source, channels: single.pieces(0, source, channels))
    return Dataset(base.procedure, base.sample_rate_hz, base.sensors, steps, base.source,
                   base.metadata)
