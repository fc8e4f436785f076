"""moto's S3 server on loopback for the benchmarks that read from object storage.

Numbers measured against it are the client path plus moto's own overhead on this machine, not
a real network or AWS S3; the scripts that use it say so in their output.
"""

from __future__ import annotations

import logging
import os
import socket
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def moto_s3() -> Iterator[str]:
    """Start moto's S3 server on a free loopback port, point aatest at it (environment, so
    worker processes inherit it); yield its endpoint URL."""
    from moto.server import ThreadedMotoServer

    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = int(probe.getsockname()[1])
    logging.getLogger("werkzeug").setLevel(logging.ERROR)  # one line per request otherwise
    server = ThreadedMotoServer(ip_address="127.0.0.1", port=port, verbose=False)
    server.start()
    endpoint = f"http://127.0.0.1:{port}"
    os.environ.update(AWS_ACCESS_KEY_ID="bench", AWS_SECRET_ACCESS_KEY="bench",
                      AWS_DEFAULT_REGION="us-east-1", AATEST_S3_ENDPOINT=endpoint)
    try:
        yield endpoint
    finally:
        server.stop()
