"""The loopback fault proxy of :mod:`tcp_proxy` for line-oriented protocols (ACUTROL, ESPEC,
SIMSERV): a trigger's ``match`` receives the request line (text) instead of a Modbus request;
reset, black hole, stall and kill act on whole lines the same way."""

from __future__ import annotations

import socket
import struct
import time

from tcp_proxy import FaultProxy, _close


class LineFaultProxy(FaultProxy):
    """Forward ``127.0.0.1:<port>`` to ``upstream_port``, requests split at ``terminator``."""

    def __init__(self, upstream_port: int, terminator: bytes = b"\n") -> None:
        super().__init__(upstream_port)
        self.terminator = terminator

    def _upstream(self, client: socket.socket, upstream: socket.socket) -> None:
        buffer = b""
        try:
            while True:
                chunk = client.recv(65536)
                if not chunk:
                    break
                buffer += chunk
                while self.terminator in buffer:
                    line, _, buffer = buffer.partition(self.terminator)
                    if not self._forward(line + self.terminator, client, upstream):
                        return
        except OSError:
            pass
        _close(client, upstream)

    def _forward(self, frame: bytes, client: socket.socket, upstream: socket.socket) -> bool:
        action = self._decide(frame.decode("latin-1"))  # type: ignore[arg-type]
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
