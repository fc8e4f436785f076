"""Selecting recordings (records options, a directory or ``file://`` URL prefix) and the
``aatest batch`` command end to end with a local cluster of worker processes."""

from __future__ import annotations

import json
from pathlib import Path

from batch_units import ARCHIVE_UNITS
from typer.testing import CliRunner

from aatest.batch.selection import from_prefix, from_store
from aatest.cli import app
from aatest.records.models import RecordFilter
from aatest.records.store import RecordStore


def aatest(*args: object) -> tuple[int, str, str]:
    result = CliRunner().invoke(app, [str(a) for a in args])
    return result.exit_code, result.stdout, result.stderr


def test_records_options_select_by_serial_and_reference(store_copy: str) -> None:
    with RecordStore.open(store_copy) as store:
        every = from_store(store, RecordFilter(include_simulations=True))
        assert sorted(s.record.serial for s in every if s.record) == \
            sorted(u.serial for u in ARCHIVE_UNITS)
        assert from_store(store, RecordFilter()) == []  # simulations only when asked
        on_log9 = from_store(store, RecordFilter(include_simulations=True), "LOG-9")
        assert sorted(s.record.serial for s in on_log9 if s.record) == \
            sorted(u.serial for u in ARCHIVE_UNITS if "LOG-9" in u.references)
        assert from_store(store, RecordFilter(include_simulations=True), "LOG-1") == []
        (one,) = from_store(store, RecordFilter(serial="B3", include_simulations=True))
        assert Path(one.recording).is_file() and one.subject == f"record:{one.record.id}"


def test_a_prefix_finds_every_recording_and_links_its_record(
        twin_archive: tuple[Path, Path], store_copy: str) -> None:
    root, _ = twin_archive
    with RecordStore.open(store_copy) as store:
        local = from_prefix(str(root / "rig-c"), store)
        as_url = from_prefix((root / "rig-c").as_uri(), store)
    assert [s.recording for s in local] == [s.recording for s in as_url]
    assert len(local) == sum(u.rig == "rig-c" for u in ARCHIVE_UNITS)
    assert all(s.record is not None and s.subject == f"record:{s.record.id}" for s in local)
    code, _, err = aatest("batch", "analyze", str(root / "nothing-here"),
                          "--records", store_copy)
    assert code == 2 and "no recording.mcap found" in err


def test_batch_diagnose_over_a_url_prefix_on_worker_processes(
        twin_archive: tuple[Path, Path], store_copy: str) -> None:
    root, _ = twin_archive
    prefix = (root / "rig-d").as_uri()
    code, out, err = aatest("batch", "diagnose", prefix, "--records", store_copy,
                            "--workers", "2", "--json")
    assert code == 0, out + err  # the archive's twin has no effect: nothing to find
    report = json.loads(out)
    wanted = sum(u.rig == "rig-d" for u in ARCHIVE_UNITS)
    assert len(report["completed"]) == wanted and report["failures"] == []
    assert all(r["overall_verdict"] == "explained" and r["record_id"] is not None
               for r in report["results"])
    assert len(report["worker_peak_mib"]) == 2
    assert err.splitlines()[-1] == "done 4 · failed 0 · remaining 0"
    code, out, err = aatest("batch", "diagnose", prefix, "--records", store_copy)
    assert code == 0 and "4 recording(s), 4 done before, 0 now, 0 failed" in out
    code, _, err = aatest("batch", "analyze", prefix, "--serial", "B1", "--records", store_copy)
    assert code == 2 and "either a PREFIX or record options" in err
