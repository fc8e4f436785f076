"""End to end with the twin: runs register, ``history`` shows them, ``verify`` checks the record.

Done-when of issue 12: two runs of the scale-factor procedure for serial A1234 appear in
``aatest history A1234`` with distinct certificate numbers, on SQLite and PostgreSQL.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from aatest.cli import app

RUNNER = CliRunner()
PROCEDURE = Path(__file__).parents[2] / "src" / "aatest" / "procedures" / "scale-factor.yaml"


def aatest(*args: str) -> tuple[int, str, str]:
    result = RUNNER.invoke(app, [str(a) for a in args])
    return result.exit_code, result.stdout, result.stderr


def _runs(url: str, root: Path, count: int = 2) -> list[Path]:
    """``count`` registered runs of the shipped scale-factor procedure (seeds 1, 2, …)."""
    runs = []
    for seed in range(1, count + 1):
        out = root / f"run{seed}"
        code, stdout, stderr = aatest("run", PROCEDURE, "--out", out, "--seed", str(seed),
                                      "--no-progress", "--records", url)
        assert code == 0, stdout + stderr
        runs.append(out)
    return runs


@pytest.fixture
def two_runs(store_url: str, tmp_path: Path) -> tuple[str, list[Path]]:
    return store_url, _runs(store_url, tmp_path)


def test_two_runs_appear_in_history_with_distinct_certificates(
        two_runs: tuple[str, list[Path]]) -> None:
    url, runs = two_runs
    code, _, stderr = aatest("history", "A1234", "--records", url, "--json")
    assert code == 2 and "2 simulation(s), never calibrations" in stderr  # twin runs
    code, stdout, stderr = aatest("history", "A1234", "--records", url, "--json",
                                  "--include-simulations")
    assert code == 0, stderr
    document = json.loads(stdout)
    assert document["serial"] == "A1234"
    numbers = [r["certificate_number"] for r in document["records"]]
    assert len(set(numbers)) == 2 and all(n.startswith("SIM-") for n in numbers)
    assert [r["bundle"] for r in document["records"]] == [
        str((run / "report.html").resolve()) for run in runs]
    for record, run in zip(document["records"], runs, strict=True):
        stated = json.loads((run / "results.json").read_text())
        assert stated["certificate_number"] == record["certificate_number"]
        assert record["certificate_number"] in (run / "report.html").read_text()
        value = stated["analysis"]["scale_factor"]["v_sz"]["scale_v_per_dps2"]
        assert record["quantities"]["scale_factor.v_sz"]["value"] == pytest.approx(value, rel=1e-12)
        assert set(record) == {"certificate_number", "procedure", "calibrated_utc",
                               "overall_verdict", "quantities", "bundle", "kind"}
        assert record["kind"] == "simulation"
    code, text, _ = aatest("history", "A1234", "--records", url, "--include-simulations")
    assert code == 0 and all(n in text for n in numbers) and "(simulation)" in text
    assert "next due:" not in text  # a simulation calibrates nothing: no due date


def test_unknown_serial_is_bad_input(sqlite_url: str, tmp_path: Path) -> None:
    _runs(sqlite_url, tmp_path, count=1)  # a store that holds another unit
    code, _, stderr = aatest("history", "Z9999", "--records", sqlite_url)
    assert code == 2 and "no calibration records of unit 'Z9999'" in stderr


def test_reanalysis_and_resigning_supersede(sqlite_url: str, tmp_path: Path) -> None:
    (run, _) = _runs(sqlite_url, tmp_path)
    first = json.loads((run / "results.json").read_text())["certificate_number"]
    assert aatest("keygen", "--no-passphrase", tmp_path / "key")[0] == 0
    code, _, stderr = aatest("report", run, "--sign-key", tmp_path / "key", "--records", sqlite_url)
    assert code == 0, stderr
    assert json.loads((run / "results.json").read_text())["certificate_number"] == first
    code, _, stderr = aatest("analyze", run, "--records", sqlite_url)
    assert code == 0, stderr
    renumbered = json.loads((run / "results.json").read_text())["certificate_number"]
    assert renumbered not in (first, None)
    code, listing, _ = aatest("records", "list", "--serial", "A1234", "--superseded",
                              "--include-simulations", "--records", sqlite_url)
    rows = [line for line in listing.splitlines() if "A1234" in line]  # below the headers
    assert code == 0 and len(rows) == 4 and listing.splitlines()[0].split()[:2] == [
        "Certificate", "Calibrated"]
    code, current, _ = aatest("records", "list", "--serial", "A1234", "--records", sqlite_url,
                              "--include-simulations")
    rows = [line for line in current.splitlines() if "A1234" in line]
    assert len(rows) == 2 and renumbered in current and first not in current


def test_verify_reports_a_recording_changed_after_registration(
        sqlite_url: str, tmp_path: Path) -> None:
    assert aatest("keygen", "--no-passphrase", tmp_path / "key")[0] == 0
    out = tmp_path / "signed"
    code, stdout, stderr = aatest("run", PROCEDURE, "--out", out, "--no-progress",
                                  "--sign-key", tmp_path / "key", "--records", sqlite_url)
    assert code == 0, stdout + stderr
    report = out / "report.html"
    trust = ("--public-key", tmp_path / "key.pub")
    code, stdout, _ = aatest("verify", report, "--records", sqlite_url, *trust)
    assert code == 0 and "matches its record SIM-" in stdout
    with (out / "recording.mcap").open("ab") as handle:
        handle.write(b"\0")
    code, _, stderr = aatest("verify", report, "--records", sqlite_url, *trust)
    assert code == 1
    assert "recording.mcap changed since it was registered (record SIM-" in stderr
    (out / "recording.mcap").unlink()
    code, _, stderr = aatest("verify", report, "--records", sqlite_url, *trust)
    assert code == 1 and "recording.mcap removed since it was registered" in stderr


def test_verify_reports_a_certificate_number_edited_and_resigned(
        sqlite_url: str, tmp_path: Path) -> None:
    """Re-signing a doctored results.json passes the signature check, but not the record."""
    from aatest.bundle import signing

    assert aatest("keygen", "--no-passphrase", tmp_path / "key")[0] == 0
    out = tmp_path / "doctored"
    assert aatest("run", PROCEDURE, "--out", out, "--no-progress", "--sign-key",
                  tmp_path / "key", "--records", sqlite_url)[0] == 0
    results = json.loads((out / "results.json").read_text())
    results["certificate_number"] = "LAB-2026-999999"
    (out / "results.json").write_text(json.dumps(results))
    signing.sign_bundle(out / "report.html", signing.load_private_key(tmp_path / "key"))
    trust = ("--public-key", tmp_path / "key.pub")
    code, _, stderr = aatest("verify", out / "report.html", "--records", sqlite_url, *trust)
    assert code == 1 and "certificate number 'LAB-2026-999999' in results.json" in stderr
    moved = out.rename(tmp_path / "moved")  # elsewhere, the record is not found by location
    code, _, stderr = aatest("verify", moved / "report.html", "--records", sqlite_url, *trust)
    assert code == 1
    assert "certificate number 'LAB-2026-999999' was never issued by sqlite:///" in stderr
    del results["certificate_number"]
    (moved / "results.json").write_text(json.dumps(results))
    signing.sign_bundle(moved / "report.html", signing.load_private_key(tmp_path / "key"))
    code, _, stderr = aatest("verify", moved / "report.html", "--records", sqlite_url, *trust)
    assert code == 1
    assert "results.json states no certificate number, and no record of this bundle" in stderr


def test_unreachable_database_exits_2_before_anything_is_recorded(tmp_path: Path) -> None:
    """The preflight reaches the records store before motion (issue 23): an unreachable one
    is refused with its URL (password masked) and no recording is started."""
    out = tmp_path / "offline"
    code, _, stderr = aatest("run", PROCEDURE, "--out", out, "--no-progress",
                             "--records", "postgresql://cal:s3cret@127.0.0.1:9/records")
    assert code == 2
    assert "postgresql+psycopg://cal:***@127.0.0.1:9/records cannot be reached" in stderr
    assert "s3cret" not in stderr
    assert not (out / "recording.mcap").exists()


def test_records_show_and_export(sqlite_url: str, tmp_path: Path) -> None:
    runs = _runs(sqlite_url, tmp_path)
    number = json.loads((runs[0] / "results.json").read_text())["certificate_number"]
    code, stdout, stderr = aatest("records", "show", number, "--records", sqlite_url)
    assert code == 0, stderr
    shown = json.loads(stdout)
    assert shown["serial"] == "A1234" and shown["bundle_problems"] == []
    assert set(shown["files"]) >= {"report.html", "results.json", "recording.mcap"}
    (runs[0] / "results.json").unlink()
    shown = json.loads(aatest("records", "show", number, "--records", sqlite_url)[1])
    assert any("results.json removed" in p for p in shown["bundle_problems"])
    target = tmp_path / "export.csv"
    code, _, stderr = aatest("records", "export", "--csv", target, "--procedure", "scale-factor",
                             "--records", sqlite_url, "--include-simulations")
    assert code == 0, stderr
    rows = list(csv.DictReader(target.open(encoding="utf-8")))
    assert rows[0]["certificate_number"] == number and len(rows) == 2
    assert float(rows[0]["scale_factor.v_sz"]) == pytest.approx(0.004014, rel=0.01)


def test_reading_a_missing_store_does_not_create_it(tmp_path: Path) -> None:
    missing = tmp_path / "nowhere.sqlite"
    code, _, stderr = aatest("records", "list", "--records", f"sqlite:///{missing}")
    assert code == 2 and "no records store at" in stderr and not missing.exists()


def test_diagnosis_is_registered_but_not_a_calibration(sqlite_url: str, tmp_path: Path) -> None:
    """What ``aatest diagnose`` wrote is recorded for the unit, without a certificate number."""
    from aatest.records.hook import register_diagnosis, registering
    from aatest.records.lab import LabProfile
    from aatest.records.models import RecordFilter
    from aatest.records.store import RecordStore

    (run,) = _runs(sqlite_url, tmp_path, count=1)
    (run / "diagnosis.html").write_text("<html>diagnosis</html>", encoding="utf-8")
    with registering(sqlite_url, LabProfile(), "diagnose") as registrar:
        record_id = register_diagnosis(registrar, run, None)
    with RecordStore.open(sqlite_url) as store:
        everything = store.query(RecordFilter(serial="A1234", include_simulations=True))
        history = store.history("A1234", include_simulations=True)
    diagnosis = next(r for r in everything if r.id == record_id)
    assert diagnosis.command == "diagnose" and diagnosis.certificate_number is None
    assert diagnosis.bundle == str((run / "diagnosis.html").resolve())
    assert "diagnosis.html" in diagnosis.files and "recording.mcap" in diagnosis.files
    assert len(history) == 1 and history[0].command == "run"
