"""Transcript tests for instrument drivers: the exact bytes a driver sends and what it gets back.

In the style of pymeasure's ``expected_protocol``: a test lists ``(request, reply)`` pairs — the
bytes the driver must send, in order, and the bytes the instrument answers (``None``: no
answer) — and runs the driver against a :class:`TranscriptServer` on a loopback port. Any
request that differs from the transcript, arrives out of order or is missing fails the test
(:meth:`TranscriptServer.verify`). Nothing is simulated: the server only replays the listed
exchange, so the transcript pins the driver's wire format to the public sources cited beside
each line.
"""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

Exchange = tuple[bytes, bytes | None]


@dataclass
class TranscriptServer:
    """Replays ``transcript`` to whatever connects to ``127.0.0.1:port`` (one client at a time).

    Parameters
    ----------
    transcript
        ``(request, reply)`` pairs; each request includes its terminator.
    """

    transcript: Sequence[Exchange]
    received: list[bytes] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        self._listener = socket.create_server(("127.0.0.1", 0))
        self.port = int(self._listener.getsockname()[1])
        self._index = 0
        self._closed = False
        self._thread = threading.Thread(target=self._serve, daemon=True, name="transcript")
        self._thread.start()

    def _serve(self) -> None:
        while not self._closed:
            try:
                client, _ = self._listener.accept()
            except OSError:
                return
            with client:
                self._converse(client)

    def _converse(self, client: socket.socket) -> None:
        buffer = b""
        while self._index < len(self.transcript):
            request, reply = self.transcript[self._index]
            while len(buffer) < len(request):
                chunk = client.recv(65536)
                if not chunk:
                    return
                buffer += chunk
            got, buffer = buffer[:len(request)], buffer[len(request):]
            self.received.append(got)
            if got != request:
                self.errors.append(f"exchange {self._index + 1}: expected {request!r}, "
                                   f"got {got!r}")
                self._index = len(self.transcript)
                return
            self._index += 1
            if reply is not None:
                client.sendall(reply)
        extra = buffer or client.recv(65536)
        if extra:
            self.errors.append(f"after the transcript: unexpected {extra!r}")

    def verify(self, timeout_s: float = 5.0) -> None:
        """Raise AssertionError unless every exchange happened exactly as listed.

        Waits up to ``timeout_s`` for the server to take in what the driver already sent
        (writes without a reply may still be in flight when the driver returns).
        """
        deadline = time.monotonic() + timeout_s
        while (self._index < len(self.transcript) and not self.errors
               and time.monotonic() < deadline):
            time.sleep(0.01)
        self._closed = True
        self._listener.close()
        if self.errors:
            raise AssertionError("; ".join(self.errors))
        if self._index != len(self.transcript):
            request = self.transcript[self._index][0]
            raise AssertionError(f"exchange {self._index + 1} ({request!r}) never came")

    def __enter__(self) -> TranscriptServer:
        return self

    def __exit__(self, *exc: object) -> None:
        if exc[0] is None:
            self.verify()
        else:
            self._closed = True
            self._listener.close()
