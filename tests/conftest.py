"""Suite-wide settings: matplotlib without a display, seeded hypothesis; and every results.json
the engine writes during the suite is validated against the committed results.schema.json."""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest
from results_schema import assert_valid_results

os.environ.setdefault("MPLBACKEND", "Agg")


@pytest.fixture(autouse=True)
def _results_match_schema(request: pytest.FixtureRequest) -> Iterator[None]:
    """After a test that used ``tmp_path``, validate the results.json files it wrote."""
    used = "tmp_path" in request.fixturenames
    tmp: Path | None = request.getfixturevalue("tmp_path") if used else None
    yield
    if tmp is not None:
        assert_valid_results(tmp)


@pytest.fixture(autouse=True, scope="session")
def _all_results_match_schema(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """At the end of the session, validate every results.json under the session's temp root
    (module-scoped fixtures write there too)."""
    yield
    assert_valid_results(tmp_path_factory.getbasetemp())
# CLI runs register calibration records: never into the user's own store (tests/records
# points each of its tests at a fresh one). The store's directory goes with the process that
# made it (each xdist worker makes its own), so runs of the suite leave none behind.
if "AATEST_RECORDS" not in os.environ:
    _RECORDS_DIR = tempfile.mkdtemp(prefix="aatest-test-records-")
    atexit.register(shutil.rmtree, _RECORDS_DIR, ignore_errors=True)
    os.environ["AATEST_RECORDS"] = "sqlite:///" + os.path.join(_RECORDS_DIR, "records.sqlite")


@pytest.fixture
def two_workers(monkeypatch: pytest.MonkeyPatch) -> None:
    """Two CPUs' worth of forked workers whatever the suite's setting, and only threads
    started by the test itself counted (a server an earlier test left running is not this
    one's); skipped where the machine gives the tests one CPU (nothing is forked there)."""
    from aatest.parallel import forked

    monkeypatch.setenv(forked.WORKERS_ENV, "2")
    stray = set(threading.enumerate())
    monkeypatch.setattr(forked, "_other_threads", lambda: [
        t.name for t in threading.enumerate()
        if t not in stray and t is not threading.current_thread()])
    if forked.cpu_workers() < 2:
        pytest.skip("this machine gives the tests one CPU: nothing is forked there")
