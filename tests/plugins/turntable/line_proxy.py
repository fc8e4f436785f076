"""The loopback fault proxy of :mod:`tcp_proxy` for line-oriented protocols (ACUTROL, ESPEC,
SIMSERV): a trigger's ``match`` receives the request line (text) instead of a Modbus request;
reset, black hole, stall and kill act on whole lines the same way."""

from __future__ import annotations

from tcp_proxy import FaultProxy


class LineFaultProxy(FaultProxy):
    """Forward ``127.0.0.1:<port>`` to ``upstream_port``, requests split at ``terminator``."""

    def __init__(self, upstream_port: int, terminator: bytes = b"\n") -> None:
        self.terminator = terminator
        super().__init__(upstream_port)

    def _split(self, buffer: bytes) -> tuple[list[bytes], bytes]:
        *lines, rest = buffer.split(self.terminator)
        return [line + self.terminator for line in lines], rest

    def _request(self, frame: bytes) -> str:
        return frame.decode("latin-1")
