"""Reference standards with due dates: registered, listed, retired; an overdue one refuses a
run before anything moves, and ``--allow-overdue`` prints the reason as a non-conformity."""

from __future__ import annotations

import json
from datetime import UTC, datetime, timedelta
from pathlib import Path

from typer.testing import CliRunner

from aatest.cli import app
from aatest.records.store import RecordStore

QUICK = Path(__file__).parents[1] / "station" / "data" / "quick-scale-factor.yaml"
TODAY = datetime.now(UTC).date()


def aatest(*args: object) -> tuple[int, str, str]:
    result = CliRunner().invoke(app, [str(a) for a in args])
    return result.exit_code, result.stdout, result.stderr


def _add(url: str, identifier: str, due_in_days: int, kind: str = "encoder") -> None:
    code, out, err = aatest(
        "references", "add", identifier, "--kind", kind, "--certificate", f"C-{identifier}",
        "--issuing-lab", "National Lab", "--calibrated", TODAY - timedelta(days=400),
        "--due", TODAY + timedelta(days=due_in_days), "--accuracy", "±1 arcsec",
        "--records", url)
    assert code == 0, out + err


def _rig(tmp_path: Path, *references: str) -> Path:
    rig = tmp_path / "rig.yaml"
    rig.write_text("turntable: {plugin: sim}\ndaq: {plugin: sim}\nchamber: {plugin: none}\n"
                   f"references: [{', '.join(references)}]\n")
    return rig


def test_add_list_retire(store_url: str) -> None:
    _add(store_url, "ENC-1", 30)
    _add(store_url, "LOG-7", -1, kind="data-logger")
    code, out, _ = aatest("references", "list", "--records", store_url)
    assert code == 0
    lines = out.splitlines()
    assert lines[0].startswith("ENC-1") and lines[0].endswith("in use")
    assert lines[1].startswith("LOG-7") and lines[1].endswith("OVERDUE")
    code, _, err = aatest("references", "add", "ENC-1", "--kind", "encoder", "--certificate",
                          "X", "--issuing-lab", "L", "--calibrated", "2026-01-01", "--due",
                          "2027-01-01", "--accuracy", "a", "--records", store_url)
    assert code == 2 and "already registered" in err
    for kind, due, problem in (("ruler", "2027-01-01", "kind: Input should be 'encoder'"),
                               ("encoder", "2025-01-01", "due date 2025-01-01 is not after")):
        code, _, err = aatest("references", "add", "BAD", "--kind", kind, "--certificate", "X",
                              "--issuing-lab", "L", "--calibrated", "2026-01-01", "--due", due,
                              "--accuracy", "a", "--records", store_url)
        assert code == 2 and problem in err, err
    assert aatest("references", "retire", "LOG-7", "--reason", "broken",
                  "--records", store_url)[0] == 0
    code, out, _ = aatest("references", "list", "--records", store_url)
    assert "LOG-7" not in out
    code, out, _ = aatest("references", "list", "--retired", "--records", store_url)
    assert "LOG-7" in out and out.splitlines()[1].endswith("retired")


def test_an_overdue_reference_refuses_the_run_before_motion(
        sqlite_url: str, tmp_path: Path) -> None:
    _add(sqlite_url, "ENC-1", 30)
    _add(sqlite_url, "LOG-7", -1, kind="data-logger")
    out = tmp_path / "run"
    code, _, err = aatest("run", QUICK, "--rig", _rig(tmp_path, "ENC-1", "LOG-7"), "--out", out,
                          "--no-progress", "--records", sqlite_url)
    assert code == 2 and "reference 'LOG-7'" in err and "was due on" in err
    assert "--allow-overdue" in err and "nothing was moved" in err
    assert not out.exists()  # refused before the run directory, the rig or any step
    code, _, err = aatest("run", QUICK, "--rig", _rig(tmp_path, "NOPE"), "--out", out,
                          "--no-progress", "--records", sqlite_url,
                          "--allow-overdue", "not for unknown ones")
    assert code == 2 and "'NOPE' is not registered" in err and not out.exists()


def test_allow_overdue_prints_the_reason_as_a_nonconformity(
        sqlite_url: str, tmp_path: Path) -> None:
    _add(sqlite_url, "ENC-1", 30)
    _add(sqlite_url, "LOG-7", -1, kind="data-logger")
    out = tmp_path / "run"
    reason = "recalibration booked for next week; checked against LOG-8 this morning"
    code, stdout, err = aatest("run", QUICK, "--rig", _rig(tmp_path, "ENC-1", "LOG-7"),
                               "--out", out, "--no-progress", "--records", sqlite_url,
                               "--allow-overdue", reason)
    assert code == 0, stdout + err
    assert "non-conformity: reference 'LOG-7'" in err and reason in err
    results = json.loads((out / "results.json").read_text())
    used = results["metadata"]["reference_standards"]
    assert [r["identifier"] for r in used] == ["ENC-1", "LOG-7"]
    (nonconformity,) = results["metadata"]["nonconformities"]
    assert "LOG-7" in nonconformity and reason in nonconformity
    report = (out / "report.html").read_text()
    assert 'id="nonconformities"' in report and reason in report
    assert 'id="reference-standards"' in report and "C-ENC-1" in report
    with RecordStore.open(sqlite_url) as store:  # the record keeps what it relied on
        (record,) = store.query_certificate(results["certificate_number"])
        stored = store.results_of(record.id).metadata.recorded("reference_standards")
    assert [r["certificate_number"] for r in stored] == ["C-ENC-1", "C-LOG-7"]
