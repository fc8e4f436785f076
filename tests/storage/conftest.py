"""A real S3-compatible server for the storage tests: moto's server mode on loopback.

Every test here talks to it over HTTP through s3fs, exactly as aatest talks to AWS S3 or MinIO;
nothing in the client is mocked. The server, its credentials and its endpoint are set in the
environment (``AATEST_S3_ENDPOINT``), so CLI subprocesses reach the same server.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from s3_server import moto_server, new_bucket, use_server


@pytest.fixture(scope="session")
def s3_endpoint() -> Iterator[str]:
    """The endpoint URL of a moto S3 server running for the whole session."""
    with moto_server() as endpoint:
        yield endpoint


@pytest.fixture
def s3_env(s3_endpoint: str, monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> str:
    """Credentials, region and endpoint of the test server; staging and records isolated."""
    use_server(monkeypatch, s3_endpoint, tmp_path)
    return s3_endpoint


@pytest.fixture
def bucket(s3_env: str) -> str:
    """A new, empty bucket on the test server; its name."""
    return new_bucket()
