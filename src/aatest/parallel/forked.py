"""Map a function over items in forked worker processes that inherit the caller's state.

Why processes: the analysis pass's per-step work (parsing the recorded blocks, the Python
around the FFTs and splines) holds the GIL, so threads side by side gained ≤ 5 % (measured,
stepped sine on the 2-core machine) while two processes use both cores. Why fork: the
function is usually a closure over a recording's lazy steps and the reductions analyses
registered on them (:meth:`aatest.recording.dataset.LazySteps.watch`), which cannot be pickled
but which a forked child has already, at no copying cost. Only the items and the (small)
results cross the process boundary.

Forking a process that runs other threads can deadlock the child (a lock held by a thread
that does not exist there), so :func:`fork_workers` is 1 — the caller's own loop — unless
this process runs one thread and the platform forks.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import signal
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from typing import Any, TypeVar, cast

from aatest.parallel.gc_freeze import frozen_for_children

T = TypeVar("T")
R = TypeVar("R")

log = logging.getLogger("aatest.workers")

#: environment variable capping the worker processes (``1``: none, the caller's own loop)
WORKERS_ENV = "AATEST_WORKERS"



@dataclass
class _ForkState:
    """What forked children inherit from the parent's map (one per process)."""

    #: the function the children call (set in the parent just before they are forked)
    task: Callable[[Any], Any] | None = None
    #: True in a forked child: it forks no workers of its own
    in_worker: bool = False


_STATE = _ForkState()
#: short jobs' threads the next forking map joins first (:func:`join_before_fork`)
_JOIN_BEFORE_FORK: list[threading.Thread] = []
_JOIN_LOCK = threading.Lock()


def cpu_workers() -> int:
    """The CPUs this process may run on, capped by ``$AATEST_WORKERS`` when that is set."""
    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        cpus = os.cpu_count() or 1
    cap = os.environ.get(WORKERS_ENV, "").strip()
    if cap.isdigit():
        cpus = min(cpus, max(1, int(cap)))
    return max(1, cpus)


def _other_threads() -> list[str]:
    """The names of the threads of this process besides the calling one."""
    return [t.name for t in threading.enumerate() if t is not threading.current_thread()]


def join_before_fork(thread: threading.Thread) -> None:
    """Have the next map that would fork join ``thread`` first: a short job started on a
    thread ahead of the maps (hashing the recording), which would otherwise keep them in one
    process (a fork beside a running thread is unsafe, see :func:`fork_workers`)."""
    with _JOIN_LOCK:
        _JOIN_BEFORE_FORK.append(thread)


def _join_short_jobs() -> None:
    with _JOIN_LOCK:
        threads = list(_JOIN_BEFORE_FORK)
        _JOIN_BEFORE_FORK.clear()
    for thread in threads:
        if thread is not threading.current_thread():
            thread.join()


def fork_workers(wanted: int) -> int:
    """How many forked workers to use for ``wanted``: at most :func:`cpu_workers`, and 1 when
    forking is unsafe here (another thread runs) or unavailable."""
    if wanted <= 1 or _STATE.in_worker or "fork" not in multiprocessing.get_all_start_methods():
        return 1
    _join_short_jobs()
    others = _other_threads()
    if others:
        log.debug("not forking workers: threads %s run in this process", others)
        return 1
    return min(wanted, cpu_workers())


def mark_worker() -> None:
    """In a child: fork no workers of its own (its task runs in this one process), and leave
    Ctrl-C to the parent (it stops the map: no traceback per worker) while SIGTERM ends the
    child at once (the parent's SIGTERM handler, inherited, would raise in the task)."""
    _STATE.in_worker = True
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _call(item: Any) -> tuple[bool, Any]:
    """In a child: ``(True, task(item))``, or ``(False, None)`` when the task raised (the
    parent then computes that item itself and meets the error with its full traceback)."""
    assert _STATE.task is not None, "parallel_map's task is set before its children fork"
    try:
        return True, _STATE.task(item)
    except Exception:  # noqa: BLE001 - reported by the parent's own call of the item
        return False, None


def parallel_map(task: Callable[[T], R], items: Sequence[T], workers: int | None = None
                 ) -> list[R]:
    """``task(item)`` of each item, in order, on up to ``workers`` forked children (default:
    one per CPU; :func:`fork_workers` decides, 1 being this process's own loop).

    The results are those of a plain loop: each item's task must depend only on the item
    and on state the children inherit. This process computes an item itself where the child
    could not hand it back — the task raised there (so the first failing item in order raises
    here, with its own traceback; items not yet started are cancelled, those running finish and
    are dropped), or its result does not pickle
    (a vendor plugin's reduction) — and every item not yet returned when a child dies (killed,
    out of memory).
    """
    items = list(items)
    count = fork_workers(len(items) if workers is None else min(workers, len(items)))
    if count <= 1:
        return [task(item) for item in items]
    if _STATE.task is not None:
        raise RuntimeError("parallel_map is not re-entrant")
    out: list[R] = []
    _STATE.task = task
    pool = ProcessPoolExecutor(max_workers=count, initializer=mark_worker,
                               mp_context=multiprocessing.get_context("fork"))
    # the children inherit this heap frozen (measured: analyse 8.0–8.7 → 7.4–7.6 s wall)
    try:
        with frozen_for_children():
            try:
                futures = [pool.submit(_call, item) for item in items]
                for item, future in zip(items, futures, strict=True):
                    out.append(_taken(future, task, item))
            except BrokenProcessPool:
                log.warning("a worker process died; %d items computed in this process",
                            len(items) - len(out))
                pool.shutdown(wait=True, cancel_futures=True)
                out += [task(item) for item in items[len(out):]]
            finally:
                pool.shutdown(wait=True, cancel_futures=True)  # an error: start nothing more
    finally:
        _STATE.task = None
    return out


def _taken(future: Future[tuple[bool, Any]], task: Callable[[T], R], item: T) -> R:
    """A child's result for ``item``, else ``task(item)`` computed here (see parallel_map).

    Raises
    ------
    BrokenProcessPool
        A child died: the caller computes the rest.
    """
    try:
        ok, result = future.result()
    except BrokenProcessPool:
        raise
    except Exception as exc:  # noqa: BLE001 - e.g. the result did not pickle: compute it here
        log.debug("item computed in this process: its worker's result failed: %r", exc)
        return task(item)
    return cast(R, result) if ok else task(item)


__all__ = ["WORKERS_ENV", "cpu_workers", "fork_workers", "mark_worker", "parallel_map"]
