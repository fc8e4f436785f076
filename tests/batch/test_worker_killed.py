"""Killing a worker process mid-batch loses no result; killing the whole batch loses only
what was running, and the re-run completes exactly what is missing.

Runs ``aatest batch analyze`` in a subprocess on a local cluster of two worker processes,
SIGKILLs one worker once a result is stored, checks the batch goes on, then SIGKILLs the
batch's whole process group, and re-runs it.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import psutil
from batch_units import ARCHIVE_UNITS
from sqlalchemy import create_engine, text

from aatest.batch import ledger
from aatest.batch.runner import run_batch
from aatest.batch.selection import from_store
from aatest.records.models import RecordFilter
from aatest.records.store import RecordStore

TIMEOUT_S = 300.0


def _stored(url: str) -> int:
    engine = create_engine(url, connect_args={"timeout": 30})
    try:
        with engine.connect() as connection:
            return int(connection.execute(text("SELECT count(*) FROM reanalyses")).scalar()
                       or 0)
    except Exception:  # noqa: BLE001 - the table appears when the batch has migrated the store
        return 0
    finally:
        engine.dispose()


def _wait(batch: subprocess.Popen[bytes], until: Callable[[], bool]) -> None:
    deadline = time.monotonic() + TIMEOUT_S
    while not until():
        assert batch.poll() is None, "the batch ended before the kill"
        assert time.monotonic() < deadline, "the batch made no progress"
        time.sleep(0.1)


def _workers(batch: subprocess.Popen[bytes]) -> list[psutil.Process]:
    """The Dask worker processes of the batch (spawned children, not the resource tracker)."""
    found = []
    for child in psutil.Process(batch.pid).children(recursive=True):
        line = " ".join(child.cmdline())
        if "spawn_main" in line and "resource_tracker" not in line:
            found.append(child)
    return found


def test_killed_worker_and_killed_batch_lose_nothing(store_copy: str, tmp_path: Path) -> None:
    log = (tmp_path / "batch.err").open("wb")
    batch = subprocess.Popen(
        [sys.executable, "-c", "from aatest.cli import main; main()", "batch", "analyze",
         "--include-simulations", "--records", store_copy, "--workers", "2"],
        stdout=subprocess.DEVNULL, stderr=log, start_new_session=True)
    try:
        _wait(batch, lambda: _stored(store_copy) >= 1)
        victim = _workers(batch)[0]
        victim.send_signal(signal.SIGKILL)
        at_kill = _stored(store_copy)
        _wait(batch, lambda: _stored(store_copy) >= at_kill + 2)  # the batch goes on
        os.killpg(batch.pid, signal.SIGKILL)  # now the whole batch dies mid-run
        batch.wait(timeout=30)
    finally:
        if batch.poll() is None:
            os.killpg(batch.pid, signal.SIGKILL)
        log.close()
    kept = _stored(store_copy)
    assert at_kill + 2 <= kept < len(ARCHIVE_UNITS), "the kill came too late to test a re-run"
    with RecordStore.open(store_copy) as store:
        assert ledger.check(store) is None  # every stored row whole and chained
        chosen = from_store(store, RecordFilter(include_simulations=True))
        report = run_batch(store, chosen, "analyze", workers=2, processes=False)
        assert report.skipped == kept and len(report.completed) == len(ARCHIVE_UNITS) - kept
        assert not report.failures
        rows = ledger.stored(store, report.method_hash)
        assert sorted(r.subject for r in rows) == sorted(s.subject for s in chosen)
        assert ledger.check(store) is None
