"""An asyncio TCP server for line-oriented ASCII instruments (ESPEC, SIMSERV, ACUTROL simulators).

:class:`LineServer` accepts any number of clients, splits what each sends at the protocol's
terminator and answers every line with what its :class:`LineProtocol` returns (``None``: no
answer, as a write-only command of a GPIB-style instrument). It runs in a background thread
with its own event loop (:class:`~aatest.twin.servers.background.BackgroundServer`, like the
Modbus server), so a test starts it in-process on port 0 and the CLI serves it for another
process (:func:`~aatest.twin.servers.background.serve_until_interrupted`).

:class:`LineFaults` lets tests make the instrument answer late or stop answering (for a
bounded time): the server side of the fault matrix; link faults (reset, black hole, stall)
come from a proxy in between.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from dataclasses import dataclass
from typing import Protocol

from aatest.twin.servers.background import BackgroundServer

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


class LineServer(BackgroundServer):
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
        super().__init__(protocol.name, host, port, lifetime_s)
        self.protocol = protocol
        self.faults = LineFaults()
        self._stopped: asyncio.Event | None = None
        self._writers: set[asyncio.StreamWriter] = set()

    def recover(self) -> None:
        """Remove injected faults: the instrument answers again."""
        self.faults = LineFaults()

    async def _serve(self) -> None:
        self._stopped = asyncio.Event()
        server = await asyncio.start_server(self._client, self.host, self.port, limit=1 << 20)
        self._listening(server.sockets[0].getsockname()[1])
        await self._stopped.wait()
        server.close()
        for writer in list(self._writers):  # like a process dying: every connection drops
            writer.close()
        with contextlib.suppress(Exception):
            await asyncio.wait_for(server.wait_closed(), 2.0)

    def _end(self) -> None:
        if self._stopped is not None:
            self._stopped.set()

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
