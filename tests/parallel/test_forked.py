"""Forked workers (:mod:`aatest.parallel.forked`): the results of a plain loop, errors raised
here in order, a dead worker's items computed here, and no fork where it is unsafe."""

from __future__ import annotations

import os
import threading

import pytest

from aatest.parallel import forked
from aatest.parallel.forked import WORKERS_ENV, cpu_workers, fork_workers, parallel_map

PARENT = os.getpid()


@pytest.fixture(autouse=True)
def _two_workers(monkeypatch: pytest.MonkeyPatch) -> None:
    """Two workers whatever the suite's setting (the machine may have one CPU: then none).

    Threads an earlier test of this pytest process left running (a server's daemon thread)
    are not counted: the rule under test is that a thread running *here* prevents the fork.
    """
    monkeypatch.setenv(WORKERS_ENV, "2")
    stray = set(threading.enumerate())
    monkeypatch.setattr(forked, "_other_threads", lambda: [
        t.name for t in threading.enumerate()
        if t not in stray and t is not threading.current_thread()])


def _square_and_pid(x: int) -> tuple[int, int]:
    return x * x, os.getpid()


def test_results_are_those_of_a_loop_in_order_computed_by_children() -> None:
    items = list(range(40))[::-1]
    out = parallel_map(_square_and_pid, items)
    assert [v for v, _ in out] == [x * x for x in items]
    pids = {pid for _, pid in out}
    if cpu_workers() >= 2:
        assert PARENT not in pids and 1 <= len(pids) <= 2, forked._other_threads()
    else:
        assert pids == {PARENT}


def test_closures_over_unpicklable_state_run_in_the_children() -> None:
    lock = threading.Lock()  # not picklable: the children inherit it, nothing is sent

    def task(x: int) -> int:
        with lock:
            return x + 1

    assert parallel_map(task, [1, 2, 3]) == [2, 3, 4]


def test_the_first_failing_item_raises_here_with_its_own_error() -> None:
    def task(x: int) -> int:
        if x in (3, 5):
            raise ValueError(f"item {x} failed in process {os.getpid()}")
        return x

    with pytest.raises(ValueError, match=f"item 3 failed in process {PARENT}$"):
        parallel_map(task, list(range(8)))


def test_a_dead_worker_leaves_its_items_to_this_process() -> None:
    def task(x: int) -> tuple[int, int]:
        if x == 2 and os.getpid() != PARENT:
            os._exit(1)  # killed, out of memory: the worker vanishes mid-task
        return _square_and_pid(x)

    out = parallel_map(task, list(range(6)))
    assert [v for v, _ in out] == [x * x for x in range(6)]
    assert out[2][1] == PARENT


def test_no_fork_while_another_thread_runs() -> None:
    stop = threading.Event()
    other = threading.Thread(target=stop.wait, name="other", daemon=True)
    other.start()
    try:
        assert fork_workers(4) == 1
        assert {pid for _, pid in parallel_map(_square_and_pid, [1, 2, 3])} == {PARENT}
    finally:
        stop.set()
        other.join()


def test_the_environment_caps_the_workers(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(WORKERS_ENV, "1")
    assert fork_workers(8) == 1
    assert {pid for _, pid in parallel_map(_square_and_pid, [1, 2, 3])} == {PARENT}


def test_a_worker_forks_no_workers_of_its_own() -> None:
    def nested(x: int) -> set[int]:
        return {pid for _, pid in parallel_map(_square_and_pid, [x, x + 1, x + 2])}

    for pids in parallel_map(nested, [0, 10]):
        assert len(pids) == 1  # the worker's own loop
    assert forked._STATE.task is None  # nothing left behind for a later map


def test_ctrl_c_stops_the_map_in_this_process_only() -> None:
    """SIGINT to the whole process group (a terminal's Ctrl-C): this process raises
    KeyboardInterrupt, the workers ignore it and are shut down, nothing is left running."""
    import signal
    import time

    if cpu_workers() < 2:
        pytest.skip("one CPU: the map runs in this process, no worker to interrupt")

    def task(x: int) -> int:
        if x == 0 and os.getpid() != PARENT:
            for pid in (PARENT, os.getpid()):  # as a terminal signals the whole group
                os.kill(pid, signal.SIGINT)
        time.sleep(0.05)
        return x

    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            parallel_map(task, list(range(40)))
    finally:
        signal.signal(signal.SIGINT, previous)
    assert forked._STATE.task is None
    assert forked._other_threads() == []  # the pool's manager thread is gone too


def test_a_result_that_does_not_pickle_is_computed_here() -> None:
    """A reduction returning something a pipe cannot carry (a lock, a generator) is computed
    by this process for that item; the other items still come from the workers."""

    def task(x: int) -> object:
        return threading.Lock() if x == 1 else (x, os.getpid())

    out = parallel_map(task, [0, 1, 2])
    assert isinstance(out[1], type(threading.Lock()))
    assert [v for v, _ in (out[0], out[2])] == [0, 2]  # type: ignore[misc]


def test_a_short_job_registered_to_be_joined_does_not_keep_the_map_in_one_process() -> None:
    # a thread left running keeps the map in this process (above); one registered with
    # join_before_fork is joined first, and the map forks as without it
    release = threading.Event()
    done: list[int] = []

    def job() -> None:
        release.wait(5.0)
        done.append(1)

    thread = threading.Thread(target=job, name="short-job")
    thread.start()
    forked.join_before_fork(thread)
    threading.Timer(0.05, release.set).start()  # ends the job a moment after the map asks
    out = parallel_map(_square_and_pid, list(range(8)))
    assert done == [1] and not thread.is_alive()
    if cpu_workers() >= 2:
        assert {pid for _, pid in out} - {PARENT}  # forked: the job was joined, not in the way
