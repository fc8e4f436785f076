"""The child process of :mod:`aatest.early.analysis`: each step file it is sent,
analysed as the analysis pass will analyse that step of ``recording.mcap``.

It builds the plan-wide view the pass sees (the plan's recorded steps, the sensors and sample
rate of the run record every step file embeds), registers the pass's watches on it
(:func:`~aatest.engine.analysis.passes.register_watches`, with the procedure's analyses and
options) and calls each applicable analysis plugin's ``early_step(data, index)``. A step's
logs are read from the shared memory the run process handed them in
(:mod:`aatest.early.handover`: the arrays a decode gives, bit for bit), else decoded from its
step file (a step not handed: the child behind by more than the handover allows, a failed
handover); its clock relation is the one the run-time check fitted when that check's inputs
are the handed arrays bit for bit, else fitted here. BLAS runs on one thread, as in the
pass, so the sums are the same. Nothing it does can fail the run: a step that raised is sent
back as None.
"""

from __future__ import annotations

import logging
import os
import signal
import socket
import warnings
from collections import deque
from collections.abc import Mapping, Sequence
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any

from aatest.early.handover import Mapped
from aatest.early.made import DRAIN, Fitted, Made, StepSent, Warned, context_digest
from aatest.engine.steps import PlannedStep
from aatest.recording.dataset import Dataset, LazySteps


def main(argv: Sequence[str]) -> None:
    """The child's entry (``argv``: the descriptors of its inbox and outbox pipes, and of its
    end of the socket handed segments come on, if any)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's: it reaps this one
    # outside a step's analyses (imports, reading its file): theirs are recorded per step
    # (_Child._analyse) and raised again where the pass takes the step
    warnings.simplefilter("ignore")
    logging.disable(logging.CRITICAL)
    inbox = Connection(int(argv[0]), writable=False)
    outbox = Connection(int(argv[1]), readable=False)
    segments = socket.socket(fileno=int(argv[2])) if argv[2:] else None
    try:
        serve(inbox, outbox, segments)
    finally:
        inbox.close()
        outbox.close()
        if segments is not None:
            segments.close()  # with any descriptor still queued in it: their memory is freed


def serve(inbox: Connection, outbox: Connection, segments: socket.socket | None = None
          ) -> None:
    """The child's loop: analyse each step named on ``inbox`` (:class:`StepSent`; its logs
    mapped from the segment on ``segments`` when handed) and send ``(step id, Made or
    None, channels read by logger or None)`` on ``outbox`` (the run process hands those of
    the next steps); keep the relations the run-time check fitted (:class:`Fitted`);
    end on ``None`` (after the step in flight: newly arrived messages are read before each
    step), on :data:`DRAIN` once every step sent before it is done, or when the parent is
    gone."""
    from threadpoolctl import threadpool_limits

    from aatest.engine import registry

    queue: deque[tuple[StepSent, Mapped | None]] = deque()
    fitted: dict[str, Any] = {}
    draining = False
    # BLAS on one thread, as in the pass (run_analyses): the same sums in the same order
    with registry.pinned(), threadpool_limits(limits=1, user_api="blas"):
        child = _Child()
        try:
            while True:
                if (not queue and not draining) or inbox.poll():
                    try:
                        message = inbox.recv()
                    except (EOFError, OSError):
                        return
                    if message is None:
                        return
                    draining = _take(message, queue, fitted, segments) or draining
                    continue
                if not queue:  # drained
                    return
                sent, mapped = queue.popleft()
                try:
                    made = child.analyse(sent.step_id, Path(sent.path), mapped,
                                         fitted.pop(sent.step_id, None))
                finally:
                    if mapped is not None:
                        mapped.close()
                read = {k: sorted(v) for k, v in mapped.read.items()} if mapped else None
                try:
                    outbox.send((sent.step_id, made, read))
                except (OSError, ValueError):
                    return
        finally:
            for _, mapped in queue:
                if mapped is not None:
                    mapped.close()


def _take(message: Any, queue: deque[tuple[StepSent, Mapped | None]],
          fitted: dict[str, Any], segments: socket.socket | None) -> bool:
    """File one message from the run process; True for :data:`DRAIN`."""
    if message == DRAIN:
        return True
    if isinstance(message, Fitted):
        fitted[message.step_id] = message.relation
    elif isinstance(message, StepSent):
        queue.append((message, _received(segments, message)))
    return False


def _received(segments: socket.socket | None, sent: StepSent) -> Mapped | None:
    """The segment of a handed step, mapped (None: not handed, or it did not come: the step
    file is decoded instead). The run process sends the descriptor before the message, so
    it is already queued; descriptors of steps whose message never came are closed."""
    if sent.handed is None or segments is None:
        return None
    while True:
        try:
            data, fds, _, _ = socket.recv_fds(segments, 1024, 1, socket.MSG_DONTWAIT)
        except OSError:  # none queued (BlockingIOError), or the socket is gone
            return None
        if not fds:
            if not data:
                return None
            continue
        try:
            if data.decode("utf-8", "replace") != sent.step_id:
                continue
            return Mapped(fds[0], sent.handed)
        except (OSError, ValueError):
            return None
        finally:
            for fd in fds:
                os.close(fd)  # a mapping keeps its memory file


class _Child:
    """The plan-wide view the child analyses each step in (from the first step file)."""

    def __init__(self) -> None:
        self._base: Dataset | None = None
        self._context = ""
        self._index: dict[str, int] = {}

    def analyse(self, step_id: str, path: Path, mapped: Mapped | None = None,
                relation: Any = None) -> Made | None:
        """Step ``step_id``'s ``early_step`` results, or None when anything failed.

        ``mapped``: its logs handed in shared memory (nothing is decoded; else the step file
        is); ``relation``: the clock relation the run-time check fitted, used when the
        handed relation inputs are those it was fitted on (nothing is fitted).
        """
        try:
            return self._analyse(step_id, path, mapped, relation)
        except Exception:  # noqa: BLE001 - the pass computes the step and meets the error
            return None

    def _analyse(self, step_id: str, path: Path, mapped: Mapped | None,
                 relation: Any) -> Made:
        from aatest.engine.analysis.passes import register_watches
        from aatest.recording import read_dataset
        from aatest.recording.step_chunks import step_digests

        if mapped is None:
            digest = step_digests(path, only={step_id})[step_id]
            single = read_dataset(path)
            base = self._base or self._first(single)
            index = self._index[step_id]
            data = _one_step_view(base, single.steps, index)
        else:
            digest = mapped.handed.digest
            base = self._base or self._first(read_dataset(path))  # its records only
            index = self._index[step_id]
            data = _handed_view(base, mapped, index, path)
        watched = register_watches(data, list(data.metadata.get("analysis", [])))
        if mapped is not None and relation is not None \
                and mapped.handed.relation_inputs_exact:
            for plugin in watched.plugins:  # the sync analysis: its watches take it
                known = getattr(plugin.cls, "known_relation", None)
                if callable(known):
                    known(data, step_id, relation)
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


def _handed_view(base: Dataset, mapped: Mapped, index: int, path: Path) -> Dataset:
    """``base`` whose step ``index`` is read from a handed segment (fresh lazy steps, as in
    :func:`_one_step_view`); channels not handed are decoded from the step file ``path``
    (the same arrays: the run process hands those the child read of the steps before)."""
    from aatest.recording import read_dataset

    decoded: list[LazySteps] = []

    def file() -> LazySteps:
        if not decoded:
            steps = read_dataset(path).steps
            assert isinstance(steps, LazySteps)
            decoded.append(steps)
        return decoded[0]

    def load(_i: int, source: str, channels: Any) -> Any:
        return mapped.log(source, channels) if mapped.holds(source, channels) \
            else file().log(0, source, channels)

    def pieces(_i: int, source: str, channels: Any) -> Any:
        return mapped.pieces(source, channels) if mapped.holds(source, channels) \
            else file().pieces(0, source, channels)

    counts: list[Mapping[str, int]] = [{} for _ in base.planned]
    counts[index] = {source: mapped.samples(source) for source in ("table", "daq")}
    steps = LazySteps(base.planned, load, counts, pieces)
    return Dataset(base.procedure, base.sample_rate_hz, base.sensors, steps, base.source,
                   base.metadata)


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
