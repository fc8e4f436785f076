"""A loopback Modbus TCP proxy that injects link faults at a chosen request.

It sits between the Modbus driver and a (simulated) controller, parses the client's Modbus TCP
frames (MBAP header, function code, register address, written values) and, at the n-th request
matching a :class:`Trigger`, either resets the connection (RST), black-holes it (nothing passes
either way until :meth:`FaultProxy.heal`), stalls that one request past the driver's timeout, or
calls the trigger's ``on_fire`` (e.g. stopping the controller's server) before forwarding it.
Everything else is forwarded byte for byte.
"""

from __future__ import annotations

import contextlib
import socket
import struct
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal

Action = Literal["reset", "blackhole", "stall", "kill"]
_MBAP = struct.Struct(">HHHB")  # transaction id, protocol id, length (unit id + PDU), unit id


@dataclass(frozen=True)
class Request:
    """One client request: function code, (write) start address and the words it writes."""

    function: int
    address: int
    values: tuple[int, ...]


def parse_request(frame: bytes) -> Request:
    """Decode the part of a Modbus TCP request the triggers look at (FC 3, 16, 23)."""
    pdu = frame[_MBAP.size:]
    function = pdu[0]
    if function == 23:  # read addr, read count, write addr, write count, byte count, values
        _ra, _rc, address, count = struct.unpack(">HHHH", pdu[1:9])
        return Request(function, address, struct.unpack(f">{count}H", pdu[10:10 + 2 * count]))
    if function == 16:
        address, count = struct.unpack(">HH", pdu[1:5])
        return Request(function, address, struct.unpack(f">{count}H", pdu[6:6 + 2 * count]))
    return Request(function, struct.unpack(">H", pdu[1:3])[0], ())


@dataclass(frozen=True)
class Trigger:
    """Apply ``action`` at the ``occurrence``-th request (1 = first) for which ``match`` holds."""

    match: Callable[[Any], bool]  # a Request (Modbus) or the request line (line protocols)
    occurrence: int
    action: Action
    stall_s: float = 1.5
    on_fire: Callable[[], None] | None = None


class FaultProxy:
    """Forward ``127.0.0.1:<port>`` to ``upstream_port``; fire ``trigger`` once.

    Modbus TCP framing by default; a protocol of other framing overrides :meth:`_split` and
    :meth:`_request` (:class:`line_proxy.LineFaultProxy`), the trigger and fault handling stay.
    """

    def __init__(self, upstream_port: int, trigger: Trigger | None = None) -> None:
        self.upstream_port = upstream_port
        self.trigger = trigger
        self.fired: Any = None
        self.blackholed = False
        self._seen = 0
        self._stall_s = 0.0
        self._stall_ends = 0.0
        self._lock = threading.Lock()
        self._listener = socket.create_server(("127.0.0.1", 0))
        self.port = int(self._listener.getsockname()[1])
        self._closed = False
        threading.Thread(target=self._accept, daemon=True, name="fault-proxy").start()

    def heal(self) -> None:
        """The operator fixed the link: disarm the trigger and let traffic pass again.

        A stalled request (and whatever the client queued behind it, e.g. its emergency stop)
        still reaches the controller when the stall ends; healing waits for that, as an operator
        who resumes a few seconds later would.
        """
        time.sleep(max(0.0, self._stall_ends - time.monotonic()))
        with self._lock:
            self.trigger, self.blackholed = None, False

    def close(self) -> None:
        self._closed = True
        self._listener.close()

    def _accept(self) -> None:
        while not self._closed:
            try:
                client, _ = self._listener.accept()
            except OSError:
                return
            try:
                upstream = socket.create_connection(("127.0.0.1", self.upstream_port), timeout=5)
            except OSError:  # the controller is gone: the client sees the connection close
                client.close()
                continue
            upstream.settimeout(None)
            threading.Thread(target=self._downstream, args=(upstream, client), daemon=True).start()
            threading.Thread(target=self._upstream, args=(client, upstream), daemon=True).start()

    def _decide(self, request: Any) -> Action | None:
        with self._lock:
            if self.blackholed:
                return "blackhole"
            trigger = self.trigger
            if trigger is None or not trigger.match(request):
                return None
            self._seen += 1
            if self._seen != trigger.occurrence:
                return None
            self.fired, self.trigger, self._stall_s = request, None, trigger.stall_s
            if trigger.action == "stall":
                self._stall_ends = time.monotonic() + trigger.stall_s + 0.2
            if trigger.on_fire is not None:
                trigger.on_fire()
            self.blackholed = trigger.action == "blackhole"
            return trigger.action

    def _split(self, buffer: bytes) -> tuple[list[bytes], bytes]:
        """The whole Modbus TCP frames at the start of ``buffer``, and the rest."""
        frames = []
        while len(buffer) >= _MBAP.size:
            end = 6 + _MBAP.unpack_from(buffer)[2]
            if len(buffer) < end:
                break
            frames.append(buffer[:end])
            buffer = buffer[end:]
        return frames, buffer

    def _request(self, frame: bytes) -> Any:
        """What a trigger's ``match`` receives for ``frame``."""
        return parse_request(frame)

    def _upstream(self, client: socket.socket, upstream: socket.socket) -> None:
        """Client → controller, one whole frame at a time, applying the trigger."""
        buffer = b""
        try:
            while chunk := client.recv(65536):
                frames, buffer = self._split(buffer + chunk)
                for frame in frames:
                    if not self._forward(frame, client, upstream):
                        return
        except OSError:
            pass
        _close(client, upstream)

    def _forward(self, frame: bytes, client: socket.socket, upstream: socket.socket) -> bool:
        action = self._decide(self._request(frame))
        if action == "reset":
            client.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
            _close(client, upstream)
            return False
        if action == "blackhole":
            return True
        if action == "stall":
            time.sleep(self._stall_s)
        upstream.sendall(frame)
        return True

    def _downstream(self, upstream: socket.socket, client: socket.socket) -> None:
        """Controller → client; answers are swallowed while the link is black-holed."""
        try:
            while True:
                chunk = upstream.recv(4096)
                if not chunk:
                    break
                if not self.blackholed:
                    client.sendall(chunk)
        except OSError:
            pass
        _close(client, upstream)


def _close(*sockets: socket.socket) -> None:
    for sock in sockets:
        with contextlib.suppress(OSError):
            sock.close()
