"""The analysis pass's per-step work, made while the run still records, in a process of its own.

Why: recording a stepped sine leaves the second core idle for much of the record phase (the
rig's critical path runs on one), while the analysis pass that follows spends most of its CPU
on work that depends on one step alone: decoding it, fitting its clock relation, resampling it
and the watched per-step reductions (FRF points, cross-correlations, evidence, temperatures).
So ``aatest run`` starts one child process at the start of the record phase, at a lower CPU
priority (it takes what the rig leaves), hands it each step file as soon as it is written —
with what the run process already has: the step's logs in shared memory, as a decode of the
file gives them (:mod:`aatest.early.handover`; ≈ 14 ms of the child's CPU a stepped-sine step
not spent decoding), and the clock relation the run-time check has just fitted on them
(:meth:`_Notifying.step_checked`; not fitted again) —, and
the child makes each step's share of the pass as the pass would (the same watches, registered
by :func:`~aatest.engine.analysis.passes.register_watches`; each analysis plugin's optional
``early_step(data, index)``; and, once the steps it reads are all made, the work a plugin's
optional ``early_ready(data, made, options)`` offers — the transfer function's fits of a test
group —, made while no step waits and taken by the plugin's ``take_early_done``). After the
record phase the pass takes those results
(``take_early(data, index, result)``) for the steps whose bytes in ``recording.mcap`` are the
ones the child decoded, or (a handed step) the ones the run process wrote the handed arrays to,
digested by the writer thread as soon as it has renamed the file into place
(:mod:`aatest.recording.step_chunks`; the run process is its run directory's one writer), and
whose plan, sensors and
analyses are the ones it watched for; every other step (missing, mismatched, failed, not yet
reached when the record phase ended — the child is then ended at once —, a resumed run's
earlier steps, a child that died) is computed in the pass as without it. Errors in the child
never fail the run; the warnings a taken step's analyses raised there are raised again when
the pass takes it, as the pass computing the step would have raised them.

Not sent: streamed steps (long static records, analysed piece by piece), and nothing at all
when the plan has no step to send or ``AATEST_EARLY_ANALYSIS=0`` (then the run is the same as
without this module: the switch lets anyone check that the results are identical).

The child is a fork of the run process when that runs no other thread yet (it then starts
with the analysis plugins already imported), else a new interpreter (a fork beside another
thread could copy a held lock) whose imports overlap the first steps; results come back over
a pipe from this child only (nothing is ever unpickled from a file). It is always reaped
(:meth:`EarlyAnalysis.close` on any exit), and it ends by itself when the run process is gone
(its pipe closes).
"""

from __future__ import annotations

import contextlib
import inspect
import logging
import os
import socket
import subprocess
import sys
import threading
import warnings
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any

from aatest.early import handover
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
from aatest.early.process import lower_priority, segment_sockets, start_child
from aatest.engine.procedure.envelope import streams_record
from aatest.engine.steps import Plan, PlannedStep
from aatest.recording.dataset import Dataset, LazySteps

log = logging.getLogger("aatest.analysis")

#: ``0`` turns the analysis during the record phase off (``aatest run`` then analyses after)
EARLY_ENV = "AATEST_EARLY_ANALYSIS"
#: how long a drain may take (s)
DRAIN_S = 600.0
#: handed segments the child may hold at once (sent, its result not back yet): one it
#: analyses (whose arrays a decode would allocate too) and one queued; they are reused, so
#: memory grows by about one step's handed logs (the channels the child reads: 10 of a
#: stepped-sine step's 16 arrays); a step beyond is sent without (the child decodes it)
MAX_HANDED = 2


@dataclass
class EarlyResults:
    """What the child made by step id; :meth:`offer` hands the valid ones to the pass."""

    made: dict[str, Made] = field(default_factory=dict)
    #: the work plugins offered once the steps it reads were made (``early_ready``), made
    later: list[LaterMade] = field(default_factory=list)
    #: steps handed to the pass by the last :meth:`offer`
    offered: int = 0
    #: whether the child had made every step sent and every item of later work when the
    #: record phase ended (its last message was :class:`~aatest.early.made.Idle`): the pass
    #: then only takes (an item still in the making was lost with the child)
    complete: bool = False

    def offer(self, data: Dataset) -> int:
        """Hand each step of ``data`` the child made of the same bytes and for the same plan,
        sensors and analyses to its plugins' ``take_early``; return how many. Never raises:
        a step not handed over is computed by the pass (which meets any error itself).
        Each :attr:`later` item made for the same plan, sensors and analyses goes to its
        plugin's ``take_early_done(data, key, value)`` (the plugin checks that it fits)."""
        try:
            self.offered = self._offer(data)
        except Exception as exc:  # noqa: BLE001 - the pass computes every step and meets it
            log.debug("analysis made while recording not used: %s", exc)
            self.offered = 0
        return self.offered

    def _offer(self, data: Dataset) -> int:
        from aatest.engine.analysis.plugins import load
        from aatest.recording.step_chunks import step_digests

        source = data.source
        if not (self.made or self.later) or not isinstance(data.steps, LazySteps) \
                or not isinstance(source, Path) or not source.is_file():
            return 0
        context = context_digest(data)
        digests = step_digests(source, only=set(self.made))
        offered = 0
        for index, step in enumerate(data.planned):
            made = self.made.get(step.id)
            if made is None or made.context != context or digests.get(step.id) != made.digest:
                continue
            takes = [(getattr(load(name).cls, "take_early", None), result)
                     for name, result in made.results.items()]
            if all(callable(take) for take, _ in takes):
                for take, result in takes:
                    take(data, index, result)  # type: ignore[misc] # checked just above
                _warn_again(made.warned)
                offered += 1
        for later in self.later:
            take_done = getattr(load(later.plugin).cls, "take_early_done", None)
            if later.context == context and callable(take_done):
                take_done(data, later.key, later.value)
        return offered


def _warn_again(warned: Sequence[Warned]) -> None:
    """Raise the warnings a taken step's analysis raised in the child, as from where they were
    raised (the run's filters decide, as for the pass's own). A class this process has not
    imported is raised as :class:`UserWarning`: nothing is imported for the child."""
    for w in warned:
        module, _, name = w.category.rpartition(".")
        found = getattr(sys.modules.get(module), name, None)
        category = found if isinstance(found, type) and issubclass(found, Warning) \
            else UserWarning
        warnings.warn_explicit(w.message, category, w.filename, w.lineno)


def enabled() -> bool:
    """False when ``AATEST_EARLY_ANALYSIS=0``."""
    return os.environ.get(EARLY_ENV, "1").strip() != "0"


def sendable(plan: Plan, envelope: Any) -> list[PlannedStep]:
    """The steps of ``plan`` a run would send: recorded and not streamed (``envelope``: the
    table's, with the DAQ's streaming capability, as the planner saw it)."""
    return [s for s in plan.steps
            if s.recorded and (envelope is None or not streams_record(s, envelope))]


def wants_early(plan: Plan) -> bool:
    """Whether an analysis the plan runs (or one it requires) makes per-step work early."""
    from aatest.engine.analysis.passes import order, requested_names

    plugins = order(requested_names(plan.analysis))
    return any(callable(getattr(p.cls, "early_step", None)) for p in plugins)


class EarlyAnalysis:
    """The child process, the pipes to it and the thread that collects what it sends.

    The child runs :func:`aatest.early.child.main` (see
    :func:`~aatest.early.process.start_child` for how it is started); the two pipes, and
    the socket the handed segments' descriptors go over (:mod:`aatest.early.handover`), are
    passed to it by descriptor. The segments are
    this object's: lent to the writer thread (:meth:`lend`), handed with a step
    (:meth:`send`), free again once the child has sent that step's result, closed with the
    child (:meth:`close`).
    """

    def __init__(self) -> None:
        to_child, self._inbox_fd = os.pipe()
        self._outbox_fd, from_child = os.pipe()
        self._segments, child_segments = segment_sockets()
        parent_ends = (self._inbox_fd, self._outbox_fd,
                       *((self._segments.fileno(),) if self._segments is not None else ()))
        try:
            self._process = start_child(to_child, from_child, parent_ends,
                                         child_segments.fileno()
                                         if child_segments is not None else None)
        except BaseException:
            os.close(self._inbox_fd)
            os.close(self._outbox_fd)
            if self._segments is not None:
                self._segments.close()
            raise
        finally:
            os.close(to_child)  # the child's ends: its exit then closes the pipe for the reader
            os.close(from_child)
            if child_segments is not None:
                child_segments.close()
        self._lock = threading.Lock()  # the writer thread and the step loop both send
        #: handed steps' segments whose result has not come back (:data:`MAX_HANDED`)
        self._handed: dict[str, handover.Segment] = {}
        #: segments the child is done with, to fill again
        self._free: list[handover.Segment] = []
        #: steps whose logs were handed over (the others the child decodes)
        self.handed_steps = 0
        #: the channels the child read of the handed steps so far, by logger: those handed
        #: of the next (None until it has told: every channel)
        self._wanted: dict[str, set[str]] = {}
        lower_priority(self._process.pid)
        self._inbox = Connection(self._inbox_fd, readable=False)
        self._outbox = Connection(self._outbox_fd, writable=False)
        self._made: dict[str, Made] = {}
        self._later: list[LaterMade] = []
        #: steps sent; the steps the child had received when it last said it was idle
        self._sent, self._idle_at = 0, -1
        self._closed = False
        self._reader = threading.Thread(target=self._collect, name="aatest-early-results",
                                        daemon=True)
        self._reader.start()

    @property
    def pid(self) -> int:
        """The child's process id (:mod:`aatest.early.child` runs there)."""
        return self._process.pid

    def send(self, step_id: str, path: Path,
             handed: tuple[handover.Handed, handover.Segment] | None = None) -> None:
        """Queue a complete step file (a dead child is no error: the pass computes it).

        ``handed``: its logs in a segment (from :meth:`lend`, filled): the descriptor goes
        over the socket first, then the message naming it.
        """
        with self._lock:
            told = None
            if handed is not None:
                try:
                    if self._segments is None or self._closed:
                        raise OSError("no child to hand to")
                    socket.send_fds(self._segments, [step_id.encode("utf-8")],
                                    [handed[1].fd])
                except OSError:  # a full socket, a dead child: decoded instead
                    self._give_back(handed[1])
                else:
                    told = handed[0]
                    self._handed[step_id] = handed[1]
                    self.handed_steps += 1
            self._sent += 1
            self._send_locked(StepSent(step_id, str(path), told))

    def lend(self) -> handover.Segment | None:
        """A segment to fill with the next step's logs (None: :data:`MAX_HANDED` are out,
        or none can be made: the child decodes the step); :meth:`send` or :meth:`give_back`
        it."""
        with self._lock:
            if self._segments is None or self._closed or len(self._handed) >= MAX_HANDED:
                return None
            if self._free:
                return self._free.pop()
        try:
            return handover.Segment()
        except OSError:
            return None

    def give_back(self, segment: handover.Segment) -> None:
        """A lent segment not handed after all."""
        with self._lock:
            self._give_back(segment)

    def _give_back(self, segment: handover.Segment) -> None:
        if self._closed:
            segment.close()
        else:
            self._free.append(segment)

    def wanted(self) -> dict[str, frozenset[str]] | None:
        """The channels to hand of the next step by logger (None: all), see :attr:`_wanted`."""
        with self._lock:
            return {k: frozenset(v) for k, v in self._wanted.items()} if self._wanted \
                else None

    def fitted(self, step_id: str, relation: Any) -> None:
        """Tell the child the clock relation the run-time check fitted on the step's logs."""
        with self._lock:
            self._send_locked(Fitted(step_id, relation))

    def _send(self, message: Any) -> None:
        with self._lock:
            self._send_locked(message)

    def _send_locked(self, message: Any) -> None:
        with contextlib.suppress(OSError, ValueError):
            self._inbox.send(message)

    def _collect(self) -> None:
        while True:
            try:
                message = self._outbox.recv()
            except Exception:  # noqa: BLE001 - the pipe's end (a child ended mid-message too)
                return
            if isinstance(message, LaterMade):
                self._later.append(message)
                continue
            if isinstance(message, Idle):
                self._idle_at = message.received
                continue
            step_id, made, read = message
            with self._lock:
                done = self._handed.pop(step_id, None)  # unmapped by the child: free again
                if done is not None:
                    self._give_back(done)
                for source, names in (read or {}).items():
                    self._wanted.setdefault(source, set()).update(names)
            if made is not None:
                self._made[step_id] = made

    def results(self, drain: bool = False) -> EarlyResults:
        """What the child made, the child ended and reaped.

        Ended at once: the steps it has not sent (the one in flight, those queued) are left
        to the pass, which computes them on every core, sooner than this one child would
        finish them (the results it has sent are in the pipe and still read). ``drain``
        (tests): after it has made every step sent.
        """
        if drain:
            self._send(DRAIN)
            with contextlib.suppress(subprocess.TimeoutExpired):
                self._process.wait(DRAIN_S)
        self.close()
        complete = self._idle_at == self._sent
        log.debug("analysis while recording: %d steps made, %d of them handed over; %s",
                  len(self._made), self.handed_steps,
                  "all made" if complete else "ended while it worked")
        return EarlyResults(dict(self._made), list(self._later), complete=complete)

    def close(self) -> None:
        """End the child (at once if it still runs) and reap it; end the reader thread."""
        if self._closed:
            return
        self._closed = True
        self._inbox.close()  # the child's next read ends its loop
        if self._process.poll() is None:
            self._process.kill()
        self._process.wait()
        self._reader.join()
        self._outbox.close()
        if self._segments is not None:
            self._segments.close()  # the child is gone: queued descriptors are freed with it
        with self._lock:
            for segment in (*self._free, *self._handed.values()):
                segment.close()
            self._free, self._handed = [], {}


class _Notifying:
    """The run's recorder, sending each step file to the child once it is written (after the
    atomic rename: the file is complete), with the step's logs in shared memory when the child
    may take them (:mod:`aatest.early.handover`), and the clock relation the run-time check
    fitted (:meth:`step_checked`). Every other attribute is the recorder's."""

    def __init__(self, recorder: Any, early: EarlyAnalysis, steps: Sequence[PlannedStep]
                 ) -> None:
        self._recorder, self._early = recorder, early
        self._ids = {s.id for s in steps}
        self._hands = "coded" in inspect.signature(recorder.write_step).parameters

    def write_step(self, step: PlannedStep, *args: Any, **kwargs: Any) -> Any:
        if step.id not in self._ids:
            return self._recorder.write_step(step, *args, **kwargs)
        logs = [*args[:2]] or [kwargs.get("table"), kwargs.get("daq")]
        segment = self._early.lend() if self._hands and "coded" not in kwargs \
            and all(log is not None for log in logs) else None
        coded: dict[str, dict[str, list[bool]]] = {}
        try:
            path = self._recorder.write_step(step, *args, **kwargs, **(
                {"coded": coded} if segment is not None else {}))
        except BaseException:
            if segment is not None:
                self._early.give_back(segment)
            raise
        handed = None if segment is None else _handed(step.id, Path(path), logs, coded,
                                                      segment, self._early.wanted())
        if segment is not None and handed is None:
            self._early.give_back(segment)
        self._early.send(step.id, Path(path), handed)
        return path

    def step_checked(self, step: PlannedStep, relation: Any) -> None:
        """The run-time check's clock relation of a step just recorded, for the child."""
        if step.id in self._ids and relation is not None:
            self._early.fitted(step.id, relation)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._recorder, name)


def _handed(step_id: str, path: Path, logs: Sequence[Any], coded: Any,
            segment: handover.Segment, wanted: Any = None
            ) -> tuple[handover.Handed, handover.Segment] | None:
    """The step's logs in a memory file as a decode of ``path`` gives them, with the digest
    of the bytes just written there (:mod:`aatest.recording.step_chunks`: what the pass
    checks ``recording.mcap`` against, so it holds for the handed arrays); None when that
    fails (the child decodes the file). ``wanted``: hand only these channels by logger
    (:func:`aatest.early.handover.layout`; a channel the child reads beyond them it decodes)."""
    from aatest.recording import format as fmt
    from aatest.recording.step_chunks import step_digests

    try:
        layouts, size, exact = handover.fill(segment, logs, coded, fmt.BLOCK_SAMPLES, wanted)
    except Exception as exc:  # noqa: BLE001 - the child decodes the step file instead
        log.debug("step %s not handed over: %s", step_id, exc)
        return None
    try:
        digest = step_digests(path, only={step_id})[step_id]
    except Exception as exc:  # noqa: BLE001 - as above
        log.debug("step %s not handed over: %s", step_id, exc)
        return None
    return handover.Handed(digest, size, fmt.BLOCK_SAMPLES, layouts, exact), segment


@dataclass
class EarlyRun:
    """What :func:`early_analysis` yields: the recorder to run the plan with, and
    :meth:`results` to call once the record phase is over."""

    recorder: Any
    analysis: EarlyAnalysis | None = None

    def results(self) -> EarlyResults | None:
        """What the child made (None without a child); the child is reaped."""
        return self.analysis.results() if self.analysis is not None else None


@contextmanager
def early_analysis(plan: Plan, recorder: Any, envelope: Any) -> Iterator[EarlyRun]:
    """Around the record phase: a child analysing the plan's sendable steps (see the module
    docstring), or none (disabled, nothing to send, no analysis makes early work). The child
    is reaped on any exit (a rig fault, Ctrl-C, an abort)."""
    possible = enabled() and os.name == "posix" and bool(sys.executable)
    steps = sendable(plan, envelope) if possible else []
    if not steps or not _wants_early_safely(plan):
        yield EarlyRun(recorder)
        return
    try:
        early = EarlyAnalysis()
    except OSError as exc:  # no process to spare: the pass analyses every step, as without
        log.debug("no analysis while recording: %s", exc)
        yield EarlyRun(recorder)
        return
    try:
        yield EarlyRun(_Notifying(recorder, early, steps), early)
    finally:
        early.close()


def _wants_early_safely(plan: Plan) -> bool:
    try:
        return wants_early(plan)
    except Exception as exc:  # noqa: BLE001 - an unloadable analysis fails in the pass, named
        log.debug("no analysis while recording: %s", exc)
        return False
