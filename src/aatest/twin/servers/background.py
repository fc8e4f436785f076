"""The start-up and serve loop every simulated instrument server shares.

A :class:`BackgroundServer` runs its asyncio server in a background thread with its own event
loop, so a test starts it in-process on port 0 (the OS picks a free port) and the CLI serves it
for another process with :func:`serve_until_interrupted`. Subclasses only say how they listen
(:meth:`BackgroundServer._serve`) and how they end (:meth:`BackgroundServer._end`).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import threading
import time
from collections.abc import Sequence
from typing import Self

from aatest.engine.errors import RigFault

log = logging.getLogger("aatest.sim")


class BackgroundServer:
    """An asyncio server in a daemon thread: ``start`` returns once the port is bound.

    Parameters
    ----------
    label
        What it simulates, for messages (``"Modbus"``, ``"espec"``).
    host, port
        Where to listen; port 0 lets the OS choose (read :attr:`port` after :meth:`start`).
    lifetime_s
        Stop by itself after this many wall seconds (``None``: run until :meth:`stop`).
    """

    def __init__(self, label: str, host: str, port: int, lifetime_s: float | None) -> None:
        self.label = label
        self.host, self.port = host, int(port)
        self.lifetime_s = lifetime_s
        self._loop: asyncio.AbstractEventLoop | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, daemon=True,
                                        name=f"sim-{label.lower()}-server")

    def start(self, timeout_s: float = 10.0) -> Self:
        """Start listening; returns once the port is bound (raises :class:`RigFault` if not)."""
        self._thread.start()
        if not self._ready.wait(timeout_s) or self._error is not None:
            raise RigFault(f"simulated {self.label} server failed to start on "
                           f"{self.host}:{self.port}: {self._error or 'timeout'}") from self._error
        return self

    def _run(self) -> None:
        try:
            asyncio.run(self._serve())
        except BaseException as exc:  # noqa: BLE001 - surfaced through start()
            self._error = exc
            self._ready.set()

    async def _serve(self) -> None:
        """Listen, call :meth:`_listening` once bound, and return when the server has ended."""
        raise NotImplementedError

    def _listening(self, port: int) -> None:
        """The port is bound (called from :meth:`_serve`): report it and arm the lifetime."""
        self._loop = asyncio.get_running_loop()
        self.port = int(port)
        log.info("simulated %s on %s:%d", self.label, self.host, self.port)
        self._ready.set()
        if self.lifetime_s is not None:
            self._loop.call_later(self.lifetime_s, self._end)

    def _end(self) -> None:
        """Make :meth:`_serve` return (runs in the server's loop)."""
        raise NotImplementedError

    def stop(self, timeout_s: float = 5.0) -> None:
        """Close the port and every connection; idempotent."""
        if self._loop is not None and self._thread.is_alive():
            with contextlib.suppress(RuntimeError):  # the loop closed meanwhile
                self._loop.call_soon_threadsafe(self._end)
        self._thread.join(timeout_s)

    @property
    def running(self) -> bool:
        """True while the server thread serves (it ends on :meth:`stop` or after lifetime_s)."""
        return self._thread.is_alive()

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


def serve_until_interrupted(servers: Sequence[BackgroundServer], banner: str,
                            extras: Sequence[object] = ()) -> None:
    """Start ``servers``, print ``banner`` (``{0}``, ``{1}``…: their ports; the line tests wait
    for), serve until Ctrl-C or until one ends, then stop ``extras`` and the servers."""
    for server in servers:
        server.start()
    try:  # the banner inside: a Ctrl-C right after it (its reader acts at once) stops cleanly
        print(banner.format(*[s.port for s in servers]), flush=True)
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
