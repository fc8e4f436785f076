"""An ``aatest sim-server …`` in a process of its own, as a separate rig would be.

Tests and conformance rigs start the simulated controller this way when the driver must reach
it across processes (the CAN logger over ``udp_multicast``, the table over TCP), and produce
the faults only a process can: ``kill -9`` (:meth:`SimServerProcess.kill`) and a controller
that stops answering altogether (:meth:`SimServerProcess.freeze`, SIGSTOP, until
:meth:`SimServerProcess.thaw`).
"""

from __future__ import annotations

import os
import select
import signal
import socket
import subprocess
import sys
from collections.abc import Sequence

#: wall seconds a sim-server may take to print its banner (it imports the twin first)
BANNER_TIMEOUT_S = 30.0


def free_port() -> int:
    """A loopback TCP port free at the moment of asking."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def multicast_group(seed: int) -> str:
    """A udp_multicast group of this process (python-can's CAN over UDP), distinct per seed."""
    return f"239.75.{10 + os.getpid() % 200}.{20 + seed % 200}"


def stop_process(process: subprocess.Popen[str]) -> None:
    """Ctrl-C a process of ours (``aatest run``, a sim-server), kill it after 10 s."""
    if process.poll() is not None:
        return
    process.send_signal(signal.SIGINT)
    try:
        process.wait(10.0)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait(5.0)


class SimServerProcess:
    """``aatest sim-server KIND --host 127.0.0.1 --port PORT ARGS…`` in its own process.

    Parameters
    ----------
    kind
        The sim-server command (``modbus``, ``acutrol``, ``espec``, ``simserv``).
    port
        TCP port to serve on (default a free one).
    args
        Further options, e.g. ``("--seed", "5", "--can-interface", "udp_multicast")``.
    env
        The environment of the process (default this one's).
    """

    def __init__(self, kind: str, port: int | None = None, args: Sequence[str] = (),
                 env: dict[str, str] | None = None) -> None:
        self.kind, self.port = kind, port or free_port()
        self.args, self.env = tuple(args), env
        self.banner = ""
        self.process: subprocess.Popen[str] | None = None

    def start(self) -> SimServerProcess:
        """Start it and wait for its banner (the line naming its ports); RuntimeError if none."""
        self.process = subprocess.Popen(
            [sys.executable, "-m", "aatest.cli", "sim-server", self.kind, "--host", "127.0.0.1",
             "--port", str(self.port), *self.args],
            stdout=subprocess.PIPE, text=True, env=self.env)
        assert self.process.stdout is not None
        ready, _, _ = select.select([self.process.stdout], [], [], BANNER_TIMEOUT_S)
        self.banner = self.process.stdout.readline() if ready else ""
        if not self.banner:
            self.stop()
            raise RuntimeError(f"aatest sim-server {self.kind} printed no banner within "
                               f"{BANNER_TIMEOUT_S:g} s")
        return self

    def _signal(self, signum: int) -> None:
        if self.process is not None and self.process.poll() is None:
            self.process.send_signal(signum)

    def kill(self) -> None:
        """``kill -9``: every connection drops, nothing is cleaned up."""
        self._signal(signal.SIGKILL)
        if self.process is not None:
            self.process.wait(10.0)

    def freeze(self) -> None:
        """SIGSTOP: the process keeps its sockets but answers nothing."""
        self._signal(signal.SIGSTOP)

    def thaw(self) -> None:
        """SIGCONT after :meth:`freeze`."""
        self._signal(signal.SIGCONT)

    @property
    def running(self) -> bool:
        return self.process is not None and self.process.poll() is None

    def restart(self) -> None:
        """After :meth:`kill`: a new process on the same port and options."""
        if self.running:
            self.thaw()
            return
        self.start()

    def stop(self) -> None:
        """Ctrl-C (then kill after 10 s); idempotent."""
        if self.process is not None:
            self.thaw()
            stop_process(self.process)

    def __enter__(self) -> SimServerProcess:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
