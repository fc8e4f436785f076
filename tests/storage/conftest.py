"""A real S3-compatible server for the storage tests: moto's server mode on loopback.

Every test here talks to it over HTTP through s3fs, exactly as aatest talks to AWS S3 or MinIO;
nothing in the client is mocked. The server, its credentials and its endpoint are set in the
environment (``AATEST_S3_ENDPOINT``), so CLI subprocesses reach the same server.
"""

from __future__ import annotations

import logging
import socket
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

ENDPOINT_ENV = "AATEST_S3_ENDPOINT"


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@pytest.fixture(scope="session")
def s3_endpoint() -> Iterator[str]:
    """The endpoint URL of a moto S3 server running for the whole session."""
    moto_server = pytest.importorskip("moto.server")
    port = _free_port()
    logging.getLogger("werkzeug").setLevel(logging.ERROR)  # one line per request otherwise
    server = moto_server.ThreadedMotoServer(ip_address="127.0.0.1", port=port, verbose=False)
    server.start()
    try:
        yield f"http://127.0.0.1:{port}"
    finally:
        server.stop()


@pytest.fixture
def s3_env(s3_endpoint: str, monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> str:
    """Credentials, region and endpoint of the test server; staging and records isolated."""
    for name, value in (("AWS_ACCESS_KEY_ID", "testing"), ("AWS_SECRET_ACCESS_KEY", "testing"),
                        ("AWS_DEFAULT_REGION", "us-east-1"), (ENDPOINT_ENV, s3_endpoint),
                        ("AATEST_STAGING", str(tmp_path / "staging")),
                        ("AATEST_RECORDS", f"sqlite:///{tmp_path / 'records.sqlite'}")):
        monkeypatch.setenv(name, value)
    for name in ("AWS_SESSION_TOKEN", "AWS_PROFILE", "AATEST_LAB", "AATEST_SIGNING_KEY",
                 "AATEST_STORAGE_OPTIONS", "AWS_ENDPOINT_URL"):
        monkeypatch.delenv(name, raising=False)
    return s3_endpoint


@pytest.fixture
def bucket(s3_env: str) -> str:
    """A new, empty bucket on the test server; its name."""
    from aatest.storage.location import filesystem

    name = f"lab-{uuid.uuid4().hex[:10]}"
    filesystem("s3").mkdir(name)
    return name
