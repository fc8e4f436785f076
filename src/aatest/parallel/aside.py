"""Calls made aside: forked processes run module-level calls while this process goes on.

Why: after the record phase the stepped sine's analysis pass was its figures — matplotlib's
import (≈ 0.3 s of CPU) and seven figures (≈ 0.55 s) drawn one after another — while the
other core stood idle, and the report's own work (typed results, uncertainty, verdicts)
waited behind them although it needs only their numbers. Inside a :func:`running` block
(the analysis pass and report of ``analyse_and_report``), the first call :func:`submit`-ted
forks a process that imports matplotlib on that idle core (the block's ``warm`` call), then
forks a second one with it imported; the two draw the figures as the analyses ask for them
(one lane each, in turn), and the results take them when they are written
(:meth:`Later.result`). A process ends after :data:`IDLE_S` without a call. Measured on the
stepped sine (2 cores, bench/end_to_end.py side by side, median of 7 rounds): the analyse and
report phases together 1.47 → 1.24 s.

A call is sent as its function (pickled by name: a module-level function) and arguments,
and its result comes back, each through a file of a private directory with a few bytes of
notice on a pipe: neither process waits for the other to read (a pipe holds 64 KB; the
stepped sine's FRF points alone are more, and sending them waited for matplotlib's import
aside). This process makes a call itself — with its full traceback if it raises — when
nothing runs aside (one CPU, ``AATEST_WORKERS=1``, a thread running here: see
:func:`aatest.parallel.forked.fork_workers`), when its arguments do not pickle, when the
call failed aside, or when its process aside died. So results are those of calling in
place; only where an error surfaces moves, from the call to the taking.
"""

from __future__ import annotations

import atexit
import logging
import os
import pickle
import shutil
import signal
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from dataclasses import dataclass, field
from multiprocessing.connection import Connection, Pipe
from pathlib import Path
from typing import Any, Generic, TypeVar

from aatest.parallel.forked import fork_workers, mark_worker
from aatest.parallel.gc_freeze import frozen_for_children

T = TypeVar("T")

log = logging.getLogger("aatest.workers")

#: the result of a call not (yet) taken from aside
_NOT_YET: Any = object()
#: processes aside at most, each a lane of calls (as many as CPUs up to this: this process
#: mostly waits for them)
_LANES = 2
#: CPUs from which calls are made aside
_LANES_FROM_CPUS = 2
#: seconds a process aside waits for its next call before it ends: its memory (matplotlib
#: and the pages this process has since changed) is not held while long analyses run
#: (bench/long_record.py: the sync figure is the only one drawn aside); a later call starts
#: new ones
IDLE_S = 0.25
#: the names of the blocks' directories: this, the pid of the block's process, a dash
_PREFIX = "aatest-aside-"


class Later(Generic[T]):
    """The result of a call made aside (or in place): :meth:`result` waits for it."""

    def __init__(self, call: Callable[..., T], args: tuple[Any, ...],
                 lane: _Lane | None = None, number: int = -1, value: Any = _NOT_YET) -> None:
        self._call, self._args, self._value = call, args, value
        self._lane, self._number = lane, number

    def result(self) -> T:
        """The call's result: taken from aside, else made here (raising as the call does)."""
        lane = self._lane
        if lane is not None:
            while self._value is _NOT_YET and self._number in lane.waiting and lane.notice():
                pass
            self._lane = None
        if self._value is _NOT_YET:
            self._value = self._call(*self._args)
        self._args = ()  # the arguments need not live on
        return self._value

    def _fill(self, value: Any) -> None:
        self._value = value


@dataclass
class _Lane:
    """One process aside, as this process sees it: where its calls go and their notices
    come from, and the calls whose results are not taken yet, by number."""

    requests: Connection
    notices: Connection
    directory: Path
    waiting: dict[int, Later[Any]] = field(default_factory=dict)
    alive: bool = True

    def notice(self) -> bool:
        """Read the next notice and fill its call's :class:`Later` from its file (a failed
        call's stays empty: made in place); False when no more notices come."""
        try:
            number, ok = self.notices.recv()
        except (EOFError, OSError):
            self.alive = False
            return False
        later = self.waiting.pop(number, None)
        path = self.directory / f"{number}.pickle"
        if ok and later is not None:
            try:
                with path.open("rb") as file:
                    later._fill(pickle.load(file))
            except Exception as exc:  # noqa: BLE001 - a lost result is made in place
                log.debug("call %d made in place: its result did not load: %r", number, exc)
        path.unlink(missing_ok=True)
        return True

    def close(self, drain: bool) -> None:
        """Read the notices (with ``drain``: all of them, the process ends after its last
        call) and close the lane; its requests are closed before (:func:`_ended`)."""
        while drain and self.alive and self.notice():
            pass
        self.alive = False
        self.waiting.clear()
        self.notices.close()


@dataclass
class _Block:
    """A :func:`running` block of this process (``parent``: a child forked from here later,
    a map's worker, calls in place): the processes aside it started (the first of each
    start, which reaps the others), the lanes of the latest, and the calls sent."""

    parent: int
    warm: Callable[[], Any] | None
    directory: Path
    started: list[int] = field(default_factory=list)
    lanes: list[_Lane] = field(default_factory=list)
    sent: int = 0


@dataclass
class _Slot:
    """This process's :func:`running` block, if one is open."""

    block: _Block | None = None


_SLOT = _Slot()


def submit(call: Callable[..., T], *args: Any) -> Later[T]:
    """``call(*args)`` aside inside a :func:`running` block (else now, here); its result
    later.

    The first call of a block starts the processes aside (and so does the first after they
    ended, idle: :data:`IDLE_S`); the calls go to their lanes in turn (the figures of an
    analysis pass cost alike).
    """
    block = _SLOT.block
    if block is None or block.parent != os.getpid():
        return Later(call, args, value=call(*args))
    try:
        payload = pickle.dumps((call, args), protocol=pickle.HIGHEST_PROTOCOL)
    except Exception as exc:  # noqa: BLE001 - e.g. a closure or a lock: made in place
        log.debug("call made in place: it does not pickle: %r", exc)
        return Later(call, args, value=call(*args))
    number = block.sent
    try:
        (block.directory / f"{number}.call").write_bytes(payload)
    except OSError as exc:  # e.g. a full disk: made in place
        log.debug("call made in place: it was not written: %r", exc)
        return Later(call, args, value=call(*args))
    for _ in range(2 * _LANES):  # each turn a lane found ended, at most one start of new ones
        lanes = _lanes(block)
        if not lanes:
            break
        lane = lanes[number % len(lanes)]
        try:
            lane.requests.send(number)
        except OSError:  # its process aside ended (idle) or died: another lane, or new ones
            lane.alive = False
            continue
        later: Later[T] = Later(call, args, lane, number)
        lane.waiting[number] = later
        block.sent += 1
        return later
    return Later(call, args, value=call(*args))


def ahead() -> None:
    """Start the open block's processes aside now, if none run (their first :func:`submit`
    would else start them): they make the block's ``warm`` call while this process goes on.

    Why: the processes are forked when the first call is sent; a caller that knows calls
    will come, and has work of its own before them, starts them ahead so their ``warm`` call
    overlaps that work. Outside a block, or where forking is unsafe (another thread runs),
    nothing is started. Processes started ahead end like the others, after :data:`IDLE_S`
    without a call once warm.
    """
    block = _SLOT.block
    if block is not None and block.parent == os.getpid():
        _lanes(block)


def _lanes(block: _Block) -> list[_Lane]:
    """The block's live lanes; when none, those of processes started now (none when forking
    is unsafe here: then calls are made in place)."""
    lanes = [lane for lane in block.lanes if lane.alive]
    if not lanes:
        lanes = block.lanes = _started(block)
    return lanes


def _started(block: _Block) -> list[_Lane]:
    """Fork the processes aside of ``block``: the first calls the block's ``warm`` (imports
    its calls will need), then forks one per further lane, which so has them too."""
    count = fork_workers(_LANES)  # one CPU: nothing aside (this process would wait for it)
    if count < _LANES_FROM_CPUS:
        return []
    pipes = [(Pipe(duplex=False), Pipe(duplex=False)) for _ in range(count)]
    with frozen_for_children():
        pid = os.fork()
        if pid == 0:  # pragma: no cover - the processes aside (their effects are tested)
            code = 1
            try:
                code = _first(pipes, block.directory, block.warm)
            finally:
                os._exit(code)
    block.started.append(pid)
    log.debug("calls made aside by %d processes (the first: pid %d)", count, pid)
    lanes = []
    for (requests_in, requests_out), (notices_in, notices_out) in pipes:
        requests_in.close()
        notices_out.close()
        lanes.append(_Lane(requests_out, notices_in, block.directory))
    return lanes


_Pipes = list[tuple[tuple[Connection, Connection], tuple[Connection, Connection]]]


def _first(pipes: _Pipes, directory: Path, warm: Callable[[], Any] | None) -> int:
    """The first process aside: warm up, fork one process per further lane, serve the
    first lane, then reap the others."""
    mark_worker()
    for (_, requests_out), (notices_in, _) in pipes:  # this process's ends of the lanes
        requests_out.close()
        notices_in.close()
    if warm is not None:
        with suppress(Exception):  # a call that needed it fails aside, and is made in place
            warm()
    others = []
    for index in range(1, len(pipes)):
        try:
            pid = os.fork()
        except OSError:  # that lane's ends closed below: its calls are made in place
            break
        if pid == 0:
            _keep_lane(pipes, index)
            return _serve(*_lane_ends(pipes, index), directory)
        others.append(pid)
    _keep_lane(pipes, 0)
    code = _serve(*_lane_ends(pipes, 0), directory)
    for pid in others:
        with suppress(ChildProcessError):
            os.waitpid(pid, 0)
    return code


def _lane_ends(pipes: _Pipes, index: int) -> tuple[Connection, Connection]:
    """A process aside's ends of lane ``index``: its requests' and its notices'."""
    (requests_in, _), (_, notices_out) = pipes[index]
    return requests_in, notices_out


def _keep_lane(pipes: _Pipes, index: int) -> None:
    """Close every lane's ends in this process aside but those of lane ``index`` (a lane
    whose process is gone then ends for this process too: its notices stop)."""
    for other in range(len(pipes)):
        if other != index:
            for end in _lane_ends(pipes, other):
                end.close()


def _serve(requests: Connection, notices: Connection, directory: Path) -> int:
    """A process aside: make each call sent on its lane until the requests end."""
    while True:
        try:
            if not requests.poll(IDLE_S):  # nothing more for now: end (memory back)
                return 0
            number = requests.recv()
        except (EOFError, OSError):
            return 0
        ok = False
        try:
            request = directory / f"{number}.call"
            call, args = pickle.loads(request.read_bytes())
            request.unlink()
            result = call(*args)
            with (directory / f"{number}.pickle").open("wb") as file:
                pickle.dump(result, file, protocol=pickle.HIGHEST_PROTOCOL)
            ok = True
        except Exception:  # noqa: BLE001 - the caller makes it in place, and raises
            pass
        try:
            notices.send((number, ok))
        except OSError:
            return 0


def _ended(block: _Block, discard: bool) -> None:
    """End the block's processes aside. Every call sent is taken first (each :class:`Later`
    then holds its result), unless ``discard``: then they are killed, and the calls they had
    not finished are made in place when their results are asked for."""
    if discard:
        for pid in block.started:  # the others end with their lanes, below
            with suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
    for lane in block.lanes:  # all first: the first process aside waits for the others
        lane.requests.close()
    for lane in block.lanes:
        lane.close(drain=not discard)
    for pid in block.started:
        with suppress(ChildProcessError):
            os.waitpid(pid, 0)
    shutil.rmtree(block.directory, ignore_errors=True)


@contextmanager
def running(warm: Callable[[], Any] | None = None) -> Iterator[None]:
    """Calls :func:`submit`-ted inside the block are made aside (when forking is safe here),
    by processes that call ``warm`` first; their results are taken by the block's end.
    Inside an open block: that block's processes serve (ended by its end). The processes
    are killed when the block raises."""
    if _SLOT.block is not None and _SLOT.block.parent == os.getpid():
        yield
        return
    _swept()
    directory = Path(tempfile.mkdtemp(prefix=f"{_PREFIX}{os.getpid()}-"))
    block = _Block(os.getpid(), warm, directory)
    _SLOT.block = block
    try:
        yield
    except BaseException:
        _SLOT.block = None
        _ended(block, discard=True)
        raise
    _SLOT.block = None
    _ended(block, discard=False)


def _swept() -> None:
    """Remove the directories of blocks whose process is gone (killed before its block
    ended: a few request and result files each); another user's are left alone."""
    for directory in Path(tempfile.gettempdir()).glob(f"{_PREFIX}*-*"):
        pid = directory.name.removeprefix(_PREFIX).split("-", 1)[0]
        if not pid.isdigit():
            continue
        try:
            os.kill(int(pid), 0)
        except ProcessLookupError:
            shutil.rmtree(directory, ignore_errors=True)
        except OSError:  # alive, another user's
            continue


def _end_at_exit() -> None:
    block = _SLOT.block
    if block is not None and block.parent == os.getpid():
        _SLOT.block = None
        _ended(block, discard=True)


atexit.register(_end_at_exit)

__all__ = ["IDLE_S", "Later", "ahead", "running", "submit"]
