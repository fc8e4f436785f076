"""``run_batch``: one task per recording, results stored as re-analyses linked to each record,
failures reported without stopping the others, a re-run doing only what is missing.

A cluster of threads (``processes=False``) keeps these cheap; the worker-kill test runs real
worker processes (test_worker_killed.py)."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import psutil
import pytest
from sqlalchemy import func, select

from aatest.batch import ledger
from aatest.batch.runner import client_for, run_batch
from aatest.batch.selection import Selected, from_store
from aatest.records.models import RecordFilter
from aatest.records.store import RecordStore
from aatest.records.tables import calibrations


def _calibration_rows(store: RecordStore) -> int:
    with store.engine.connect() as connection:
        return int(connection.execute(select(func.count()).select_from(calibrations)).scalar())


def test_reanalyses_are_linked_and_a_rerun_skips_them(store_copy: str) -> None:
    with RecordStore.open(store_copy) as store:
        chosen = from_store(store, RecordFilter(include_simulations=True))[:3]
        before = _calibration_rows(store)
        lines: list[str] = []
        report = run_batch(store, chosen, "analyze", workers=2, processes=False,
                           progress=lines.append)
        assert sorted(report.completed) == sorted(s.subject for s in chosen)
        assert not report.failures and lines[-1] == "done 3 · failed 0 · remaining 0"
        stored = {r.record_id: r for r in ledger.stored(store, report.method_hash)}
        for item in chosen:
            assert item.record is not None
            redone = stored[item.record.id]
            assert redone.subject == f"record:{item.record.id}"
            assert redone.aatest_version and redone.method_hash == report.method_hash
            # same recording, same code: the analysis is deterministic (seeded splits);
            # 1e-9 leaves room for BLAS summation order under another thread count
            old = item.record.quantities["scale_factor.v_sz"].value
            assert redone.quantities["scale_factor.v_sz"]["value"] == \
                pytest.approx(old, rel=1e-9)
            assert redone.overall_verdict == item.record.overall_verdict
        again = run_batch(store, chosen, "analyze", workers=1, processes=False)
        assert (again.skipped, again.completed, again.failures) == (3, [], [])
        assert _calibration_rows(store) == before  # no certificate record written or changed
        assert store.check_chain().broken is None and ledger.check(store) is None


def test_a_failing_task_is_reported_and_the_others_complete(store_copy: str,
                                                            tmp_path: Path) -> None:
    with RecordStore.open(store_copy) as store:
        good = from_store(store, RecordFilter(include_simulations=True))[:2]
        source = Path(good[0].recording)
        broken = tmp_path / "broken" / "recording.mcap"
        broken.parent.mkdir()
        broken.write_bytes(source.read_bytes()[: source.stat().st_size // 2])  # truncated
        chosen = [*good, Selected(str(broken), str(broken))]
        report = run_batch(store, chosen, "analyze", workers=2, processes=False)
        assert sorted(report.completed) == sorted(s.subject for s in good)
        (failure,) = report.failures
        assert failure.recording == str(broken) and "RecordingError" in failure.error
        shutil.copyfile(source, broken)  # the recording is restored (e.g. re-uploaded)
        again = run_batch(store, chosen, "analyze", workers=1, processes=False)
        assert (again.skipped, again.completed, again.failures) == (2, [str(broken)], [])
        assert ledger.check(store) is None


def test_diagnose_and_analyze_are_different_methods(store_copy: str) -> None:
    with RecordStore.open(store_copy) as store:
        chosen = from_store(store, RecordFilter(serial="B1", include_simulations=True))
        analysed = run_batch(store, chosen, "analyze", workers=1, processes=False)
        diagnosed = run_batch(store, chosen, "diagnose", workers=1, processes=False)
        assert analysed.method_hash != diagnosed.method_hash
        assert diagnosed.completed == [chosen[0].subject]
        (row,) = ledger.stored(store, diagnosed.method_hash)
        # the twin of the archive has no effect switched on: nothing beyond the noise
        assert row.overall_verdict == "explained" and row.outcome["findings"] == []


@pytest.mark.parametrize("processes", [False, True])
def test_the_local_cluster_listens_on_loopback_only(processes: bool) -> None:
    with client_for(None, 1, processes):
        this = psutil.Process(os.getpid())
        listening = [c.laddr.ip for p in (this, *this.children(recursive=True))
                     for c in p.net_connections() if c.status == psutil.CONN_LISTEN]
    assert listening and set(listening) == {"127.0.0.1"}


def test_an_unreachable_scheduler_is_bad_input(store_copy: str,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    from aatest.batch import runner
    from aatest.engine.errors import InputError

    monkeypatch.setattr(runner, "CONNECT_TIMEOUT_S", 2.0)
    with RecordStore.open(store_copy) as store:
        chosen = from_store(store, RecordFilter(serial="B2", include_simulations=True))
        with pytest.raises(InputError, match=r"--scheduler tcp://127.0.0.1:1: cannot connect"):
            run_batch(store, chosen, "analyze", scheduler="tcp://127.0.0.1:1")
        assert ledger.stored(store) == []
