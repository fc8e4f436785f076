"""The child process of :mod:`aatest.early.analysis`: each step file it is sent,
analysed as the analysis pass will analyse that step of ``recording.mcap``.

It builds the plan-wide view the pass sees (the plan's recorded steps, the sensors and sample
rate of the run record every step file embeds), registers the pass's watches on it
(:func:`~aatest.engine.analysis.passes.register_watches`, with the procedure's analyses and
options) and calls each applicable analysis plugin's ``early_step(data, index)``; it makes
the work plugins offer once the steps it reads are made (``early_ready``: :class:`_Later`)
while no step waits. A step's logs are read from the shared memory the run process handed
them in
(:mod:`aatest.early.handover`: the arrays a decode gives, bit for bit), else decoded from its
step file (a step not handed: the child behind by more than the handover allows, a failed
handover); its clock relation is the one the run-time check fitted when that check's inputs
are the handed arrays bit for bit, else fitted here. BLAS runs on one thread, as in the
pass, so the sums are the same. Nothing it does can fail the run: a step that raised is sent
back as None.
"""

from __future__ import annotations

import contextlib
import functools
import logging
import os
import signal
import socket
import warnings
from collections import deque
from collections.abc import Callable, Iterator, Mapping, Sequence
from multiprocessing.connection import Connection
from pathlib import Path
from typing import TYPE_CHECKING, Any

from aatest.early.handover import Mapped
from aatest.early.made import (
    DRAIN,
    Fitted,
    Idle,
    LaterMade,
    Made,
    StepSent,
    Warned,
    context_digest,
)
from aatest.engine.steps import PlannedStep
from aatest.recording.dataset import Dataset, LazySteps

if TYPE_CHECKING:
    from aatest.engine.analysis.passes import Watched


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
    while no step waits, make a piece of the work the plugins offered once the steps it
    reads were made and send each item's :class:`LaterMade` (:class:`_Later`); whenever
    all is made, send :class:`Idle` once before waiting; end on ``None`` (after the step or
    piece in flight: newly arrived messages are read before each), on :data:`DRAIN` once
    every step sent before it and every item offered are made, or when the parent is
    gone."""
    from threadpoolctl import threadpool_limits

    from aatest.engine import registry

    queue: deque[tuple[StepSent, Mapped | None]] = deque()
    fitted: dict[str, Any] = {}
    draining = False
    received, told_idle = 0, -1  # steps received; that count when the child last said Idle
    send = functools.partial(_sent, outbox)
    # BLAS on one thread, as in the pass (run_analyses): the same sums in the same order
    with registry.pinned(), threadpool_limits(limits=1, user_api="blas"):
        later = _Later(send)
        child = _Child(later)
        try:
            while True:
                idle = not queue and not draining and not later.pending
                if idle and told_idle != received:  # all made: say so once, then wait
                    told_idle = received
                    if not send(Idle(received)):
                        return
                if idle or inbox.poll():
                    message = _message(inbox)
                    if message is None:
                        return
                    received += isinstance(message, StepSent)
                    draining = _take(message, queue, fitted, segments) or draining
                    continue
                # a step, else (none waits) a piece of later work; drained: every step,
                # then every item offered, made
                going = send(_next(child, queue, fitted)) if queue else \
                    later.pending and later.advance()
                if not going:
                    return
        finally:
            for _, mapped in queue:
                if mapped is not None:
                    mapped.close()


def _message(inbox: Connection) -> Any:
    """The next message from the run process (None: the end, or it is gone)."""
    try:
        return inbox.recv()
    except (EOFError, OSError):
        return None


def _sent(outbox: Connection, message: Any) -> bool:
    """Send ``message`` on ``outbox``; False when the run process is gone."""
    try:
        outbox.send(message)
    except (OSError, ValueError):
        return False
    return True


def _next(child: _Child, queue: deque[tuple[StepSent, Mapped | None]],
          fitted: dict[str, Any]) -> tuple[str, Made | None, dict[str, list[str]] | None]:
    """The message for the run process of the first queued step, made."""
    sent, mapped = queue.popleft()
    try:
        made = child.analyse(sent.step_id, Path(sent.path), mapped,
                             fitted.pop(sent.step_id, None))
    finally:
        if mapped is not None:
            mapped.close()
    read = {k: sorted(v) for k, v in mapped.read.items()} if mapped else None
    return (sent.step_id, made, read)


class _Later:
    """The work plugins offer once the steps it reads are made (``early_ready``: e.g. a
    test group's model fits), made in this process piece by piece while no step waits,
    each item sent on as a :class:`LaterMade` (an item that raised is not sent: the pass
    makes it and meets the error).

    An item is a generator that pauses between pieces of a few milliseconds (its value is
    the generator's return value), so a step that comes waits at most one piece. Why not a
    thread or a process: measured on the stepped sine (a group's fits ≈ 0.2 s of CPU, a
    step every ≈ 60 ms), an item on a thread slowed the steps' analysis so (both contending
    for the GIL at every NumPy call) that the child fell behind by 26–40 steps, and an item
    in a forked process cost the child ≈ 1.4 s of CPU more per run (its writes copied the
    pages the fork shared) and it fell behind too. In pieces, the item takes only the time
    the child would have waited. Its warnings are ignored, like those of the pass's workers.
    """

    def __init__(self, send: Callable[[Any], bool]) -> None:
        self._send = send
        self._items: deque[tuple[str, str, Callable[[], Any], str]] = deque()
        #: the item being made: plugin, key, context and its pieces
        self._current: tuple[str, str, str, Iterator[Any]] | None = None

    @property
    def pending(self) -> bool:
        """Whether an item is queued or being made."""
        return self._current is not None or bool(self._items)

    def put(self, plugin: str, key: str, work: Callable[[], Any], context: str) -> None:
        """Queue one item: ``work()`` is a generator whose return value is the value of
        ``plugin``'s ``key``."""
        self._items.append((plugin, key, work, context))

    def advance(self) -> bool:
        """Make the next piece of the current (else the next) item; send its value once it is
        made. False when the run process is gone."""
        if self._current is None:
            plugin, key, work, context = self._items.popleft()
            try:
                self._current = (plugin, key, context, iter(work()))
            except Exception:  # noqa: BLE001 - see the class docstring
                return True
        plugin, key, context, pieces = self._current
        try:
            next(pieces)
        except StopIteration as made:
            self._current = None
            return self._send(LaterMade(plugin, key, context, made.value))
        except Exception:  # noqa: BLE001 - see the class docstring
            self._current = None
        return True


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

    def __init__(self, later: _Later | None = None) -> None:
        #: the work plugins offer once the steps it reads are made (None: none is made)
        self._later = later
        self._base: Dataset | None = None
        self._context = ""
        self._index: dict[str, int] = {}
        #: each made step's ``early_step`` results by plugin name, by step index
        self._made: dict[int, dict[str, Any]] = {}
        #: the work plugins offered (``early_ready``), by (plugin, key): each is queued once
        self._offered: set[tuple[str, str]] = set()

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
        self._made[index] = results
        if self._later is not None:
            with contextlib.suppress(Exception):  # the step is made; the pass does the rest
                self._queue_later(base, watched, self._later)
        return Made(digest, self._context, results, warned)

    def _queue_later(self, base: Dataset, watched: Watched, later: _Later) -> None:
        """Queue the work each plugin's ``early_ready`` offers now that one more step is
        made (asked of the plan-wide view ``base``; each item once)."""
        for plugin in watched.plugins:
            ready = getattr(plugin.cls, "early_ready", None)
            if not callable(ready) or not plugin.cls().applies_to(base):
                continue
            for key, work in ready(base, self._made, watched.chosen).items():
                if (plugin.name, key) not in self._offered:
                    self._offered.add((plugin.name, key))
                    later.put(plugin.name, key, work, self._context)


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
