"""The early-analysis child as a process: started (forked or a new interpreter), at a lower
CPU priority, and reaped (:mod:`aatest.early.analysis` runs it; :mod:`aatest.early.child` is
its loop).
"""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import threading
import time

#: the child's niceness increment: it runs on what the record phase leaves of the CPUs
NICENESS = 10
#: the child's program: the module imported under its own name (its records unpickle here)
CHILD_MAIN = "import sys; from aatest.early.child import main; main(sys.argv[1:])"


class Forked:
    """A forked child's handle, with the part of :class:`subprocess.Popen` this module uses."""

    def __init__(self, pid: int) -> None:
        self.pid = pid
        self._status: int | None = None

    def poll(self) -> int | None:
        """The child's exit status once it has ended (and is reaped), else None."""
        if self._status is None:
            pid, status = os.waitpid(self.pid, os.WNOHANG)
            if pid:
                self._status = os.waitstatus_to_exitcode(status)
        return self._status

    def wait(self, timeout: float | None = None) -> int:
        """Reap the child and return its exit status, as :meth:`subprocess.Popen.wait`.

        ``timeout`` (s): raise :class:`subprocess.TimeoutExpired` when the child still runs
        after it (polled every 10 ms: ``waitpid`` itself has no timeout); None waits until
        the child ends.
        """
        if timeout is None:
            if self._status is None:
                _, waited = os.waitpid(self.pid, 0)
                self._status = os.waitstatus_to_exitcode(waited)
            return self._status
        deadline_s = time.monotonic() + timeout
        while (status := self.poll()) is None:
            if time.monotonic() >= deadline_s:
                raise subprocess.TimeoutExpired(f"early-analysis child {self.pid}", timeout)
            time.sleep(0.01)
        return status

    def kill(self) -> None:
        """SIGKILL (a child already ended and reaped is left alone)."""
        if self._status is None:
            with contextlib.suppress(ProcessLookupError):
                os.kill(self.pid, signal.SIGKILL)


def segment_sockets() -> tuple[socket.socket | None, socket.socket | None]:
    """The run's and the child's ends of the socket handed segments' descriptors go over
    (None, None where memory files or descriptor passing do not exist: nothing is handed).
    The run's end never blocks: a step whose descriptor does not fit is decoded instead."""
    if not hasattr(os, "memfd_create") or not hasattr(socket, "send_fds"):
        return None, None
    try:
        ours, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
    except OSError:
        return None, None
    ours.setblocking(False)
    return ours, theirs


def start_child(to_child: int, from_child: int, parent_ends: tuple[int, ...],
                 segments: int | None = None) -> subprocess.Popen[bytes] | Forked:
    """Start the child: forked when this process runs no other thread, else a new interpreter.

    Why fork when it is safe: the child then starts with the analysis plugins this process
    has already imported (the procedure's check loaded them), instead of importing numpy,
    scipy and aatest again (measured ≈ 1.6 s of CPU, all of it taken from the record phase
    it overlaps). A fork beside another thread could copy a lock that thread holds, so
    then (and where fork does not exist) it is a fresh interpreter (``subprocess``), which
    imports only aatest, not this process's main module.
    """
    fds = (to_child, from_child, *((segments,) if segments is not None else ()))
    if hasattr(os, "fork") and threading.active_count() == 1:
        pid = os.fork()
        if pid == 0:  # the child: never returns
            _forked_main(fds, parent_ends)
        return Forked(pid)
    return subprocess.Popen(
        [sys.executable, "-c", CHILD_MAIN, *map(str, fds)],
        pass_fds=fds, stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, close_fds=True)


def _forked_main(fds: tuple[int, ...], parent_ends: tuple[int, ...]) -> None:
    """The forked child's whole life: serve, then ``os._exit`` (never the parent's exit
    handlers, nor a second flush of the parent's buffered output)."""
    code = 1
    try:
        for fd in parent_ends:
            os.close(fd)
        from aatest.early.child import main

        main([str(fd) for fd in fds])
        code = 0
    finally:
        os._exit(code)


def lower_priority(pid: int | None) -> None:
    """Lower the child's CPU priority by :data:`NICENESS` from its start (its imports too)."""
    try:
        if pid is not None:
            os.setpriority(os.PRIO_PROCESS, pid,
                           os.getpriority(os.PRIO_PROCESS, 0) + NICENESS)
    except OSError:  # a platform without it: the child runs at the run's priority
        pass
