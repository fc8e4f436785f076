"""A real S3-compatible server for tests: moto's server mode on loopback (a named module, so
the storage and batch tests share it without ``from conftest import``).

Tests talk to it over HTTP through s3fs, exactly as aatest talks to AWS S3 or MinIO; nothing in
the client is mocked. Its endpoint and credentials go into the environment
(``AATEST_S3_ENDPOINT``), so CLI subprocesses and Dask worker processes reach the same server.
"""

from __future__ import annotations

import logging
import socket
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

ENDPOINT_ENV = "AATEST_S3_ENDPOINT"


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@contextmanager
def moto_server() -> Iterator[str]:
    """Run moto's S3 server on a free loopback port; yield its endpoint URL."""
    server_module = pytest.importorskip(
        "moto.server", reason="moto[server] is not installed: no S3-compatible server here")
    port = _free_port()
    logging.getLogger("werkzeug").setLevel(logging.ERROR)  # one line per request otherwise
    server = server_module.ThreadedMotoServer(ip_address="127.0.0.1", port=port, verbose=False)
    server.start()
    try:
        yield f"http://127.0.0.1:{port}"
    finally:
        server.stop()


def use_server(monkeypatch: pytest.MonkeyPatch, endpoint: str, tmp_path: Path) -> None:
    """Point aatest at ``endpoint`` with test credentials; staging and records isolated."""
    for name, value in (("AWS_ACCESS_KEY_ID", "testing"), ("AWS_SECRET_ACCESS_KEY", "testing"),
                        ("AWS_DEFAULT_REGION", "us-east-1"), (ENDPOINT_ENV, endpoint),
                        ("AATEST_STAGING", str(tmp_path / "staging")),
                        ("AATEST_RECORDS", f"sqlite:///{tmp_path / 'records.sqlite'}")):
        monkeypatch.setenv(name, value)
    for name in ("AWS_SESSION_TOKEN", "AWS_PROFILE", "AATEST_LAB", "AATEST_SIGNING_KEY",
                 "AATEST_STORAGE_OPTIONS", "AWS_ENDPOINT_URL"):
        monkeypatch.delenv(name, raising=False)


def new_bucket() -> str:
    """A new, empty bucket on the server the environment names; its name."""
    from aatest.storage.location import filesystem

    name = f"lab-{uuid.uuid4().hex[:10]}"
    filesystem("s3").mkdir(name)
    return name
