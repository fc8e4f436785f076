"""An asyncio TCP server for line-oriented ASCII instruments (ESPEC, SIMSERV, ACUTROL simulators).

:class:`LineServer` accepts any number of clients, splits what each sends at the protocol's
terminator and answers every line with what its :class:`LineProtocol` returns (``None``: no
answer, as a write-only command of a GPIB-style instrument). It runs in a background thread
with its own event loop, like :class:`aatest.twin.servers.modbus_server.SimModbusServer`, so a
test starts it in-process on port 0 and the CLI serves it for another process.

:class:`LineFaults` lets tests make the instrument answer late or stop answering (for a
bounded time): the server side of the fault matrix; link faults (reset, black hole, stall)
come from a proxy in between.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

from aatest.engine.errors import RigFault

log = logging.getLogger("aatest.sim.line")


class LineProtocol(Protocol):
    """What a simulated instrument does with one received line."""

    #: bytes that end a request (the server also strips a trailing ``\\r``)
    terminator: bytes
    #: a short name for log lines and start-up messages
    name: str

    def answer(self, line: str) -> str | None:
        """The reply to ``line`` (without terminator or header), ``None`` for none."""

    def frame(self, reply: str) -> bytes:
        """``reply`` as sent on the wire (header, encoding, terminator)."""


@dataclass
class LineFaults:
    """Faults the simulated instrument produces on purpose (tests only; all bounded)."""

    #: every answer is delayed this long (wall seconds)
    response_delay_s: float = 0.0
    #: stop answering (requests are read and dropped) until :meth:`LineServer.recover`
    hanging: bool = False
    #: from the request containing this text on, stop answering
    hang_on: str | None = None


class LineServer:
    """Serve a :class:`LineProtocol` on ``host:port`` from a background thread.

    Parameters
    ----------
    protocol
        The simulated instrument.
    host, port
        Where to listen; port 0 lets the OS choose (read :attr:`port` after :meth:`start`).
    lifetime_s
        Stop by itself after this many wall seconds (``None``: run until :meth:`stop`).
    """

    def __init__(self, protocol: LineProtocol, host: str = "127.0.0.1", port: int = 0,
                 lifetime_s: float | None = None) -> None:
        self.protocol = protocol
        self.host, self.port = host, int(port)
        self.lifetime_s = lifetime_s
        self.faults = LineFaults()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._server: asyncio.Server | None = None
        self._stopped: asyncio.Event | None = None
        self._writers: set[asyncio.StreamWriter] = set()
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, daemon=True,
                                        name=f"sim-{protocol.name}-server")

    def start(self, timeout_s: float = 10.0) -> LineServer:
        """Start listening; returns once the port is bound (raises :class:`RigFault` if not)."""
        self._thread.start()
        if not self._ready.wait(timeout_s) or self._error is not None:
            raise RigFault(f"simulated {self.protocol.name} server failed to start on "
                           f"{self.host}:{self.port}: {self._error or 'timeout'}") from self._error
        return self

    def recover(self) -> None:
        """Remove injected faults: the instrument answers again."""
        self.faults = LineFaults()

    def _run(self) -> None:
        try:
            asyncio.run(self._serve())
        except BaseException as exc:  # noqa: BLE001 - surfaced through start()
            self._error = exc
            self._ready.set()

    async def _serve(self) -> None:
        self._loop = asyncio.get_running_loop()
        self._stopped = asyncio.Event()
        self._server = await asyncio.start_server(self._client, self.host, self.port,
                                                  limit=1 << 20)
        self.port = int(self._server.sockets[0].getsockname()[1])
        log.info("simulated %s on %s:%d", self.protocol.name, self.host, self.port)
        self._ready.set()
        if self.lifetime_s is not None:
            self._loop.call_later(self.lifetime_s, self._stopped.set)
        await self._stopped.wait()
        self._server.close()
        for writer in list(self._writers):  # like a process dying: every connection drops
            writer.close()
        with contextlib.suppress(Exception):
            await asyncio.wait_for(self._server.wait_closed(), 2.0)

    async def _client(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self._writers.add(writer)
        try:
            while True:
                try:
                    raw = await reader.readuntil(self.protocol.terminator)
                except asyncio.IncompleteReadError:
                    return
                line = raw[:-len(self.protocol.terminator)].rstrip(b"\r").decode("latin-1")
                reply = await self._answer(line)
                if reply is not None:
                    writer.write(self.protocol.frame(reply))
                    await writer.drain()
        except (ConnectionError, asyncio.LimitOverrunError, OSError) as exc:
            log.debug("client dropped: %s", exc)
        finally:
            self._writers.discard(writer)
            writer.close()

    async def _answer(self, line: str) -> str | None:
        faults = self.faults
        if faults.hang_on is not None and faults.hang_on.lower() in line.lower():
            faults.hanging = True
        if faults.hanging:
            return None
        if faults.response_delay_s:
            await asyncio.sleep(faults.response_delay_s)
        # the protocol may run the twin for seconds (a record): off the event loop
        return await asyncio.to_thread(self.protocol.answer, line)

    def stop(self, timeout_s: float = 5.0) -> None:
        """Close the port and every connection; idempotent."""
        if self._loop is not None and self._stopped is not None and self._thread.is_alive():
            with contextlib.suppress(RuntimeError):
                self._loop.call_soon_threadsafe(self._stopped.set)
        self._thread.join(timeout_s)

    @property
    def running(self) -> bool:
        """True while the server thread serves."""
        return self._thread.is_alive()

    def __enter__(self) -> LineServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


def serve_until_interrupted(servers: list[LineServer], banner: str,
                            extras: Sequence[object] = ()) -> None:
    """Start ``servers``, print ``banner`` (the port line tests wait for), serve until Ctrl-C."""
    for server in servers:
        server.start()
    print(banner.format(*[s.port for s in servers]), flush=True)
    try:
        while all(s.running for s in servers):
            time.sleep(0.5)
    except KeyboardInterrupt:
        pass
    finally:
        for part in extras:
            stop = getattr(part, "stop", None)
            if stop is not None:
                stop()
        for server in servers:
            server.stop()
