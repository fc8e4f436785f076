"""``aatest sim-server espec|simserv`` serve a simulated chamber in their own process."""

from __future__ import annotations

import select
import signal
import socket
import subprocess
import sys

import pytest


@pytest.mark.parametrize(("kind", "request_bytes", "reply_part"), [
    ("espec", b"ROM?\r\n", b"SIMULATOR"),  # ESPEC P300 ROM? (ChamberConnectLibrary p300.py)
    ("simserv", b"99997\xb61\xb61\r", b"SIMULATOR"),  # SIMSERV info 99997, chamber 1, field 1
])
def test_sim_server_chamber_answers_as_a_simulator(kind: str, request_bytes: bytes,
                                                   reply_part: bytes) -> None:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    process = subprocess.Popen([sys.executable, "-m", "aatest.cli", "sim-server", kind,
                                "--port", str(port)], stdout=subprocess.PIPE, text=True)
    try:
        assert process.stdout is not None
        ready, _, _ = select.select([process.stdout], [], [], 60.0)
        assert ready and f"127.0.0.1:{port}" in process.stdout.readline()
        with socket.create_connection(("127.0.0.1", port), timeout=10) as client:
            client.sendall(request_bytes)
            assert reply_part in client.makefile("rb").readline()
    finally:
        process.send_signal(signal.SIGINT)
        assert process.wait(10.0) == 0  # Ctrl-C is a clean stop
