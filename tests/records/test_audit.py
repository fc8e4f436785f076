"""Nothing is edited, only superseded: ``records supersede`` and the append-only audit trail."""

from __future__ import annotations

from pathlib import Path

from sqlalchemy import create_engine, text
from typer.testing import CliRunner

from aatest.bundle import observers as bundle_observers
from aatest.cli import app
from aatest.records.commands import verify_against_record
from aatest.records.hook import registering
from aatest.records.lab import LabProfile
from aatest.records.url import resolve_url
from aatest.results import RunResults

LAB = LabProfile(name="Audit Lab", certificate_prefix="AUD")


def aatest(*args: object) -> tuple[int, str, str]:
    result = CliRunner().invoke(app, [str(a) for a in args])
    return result.exit_code, result.stdout, result.stderr


def _certificate(url: str, folder: Path) -> tuple[str, Path]:
    results = RunResults.model_validate({"procedure": "audit", "metadata": {
        "sensor": {"model": "sr207", "serial": "U1"}}})
    folder.mkdir()
    bundle = folder / "report.html"
    with registering(url, LAB, "run"):
        bundle_observers.before_signing(results)
        bundle.write_text(f"<html>{results.certificate_number}</html>")
        bundle_observers.after_signing(results, bundle)
    return str(results.certificate_number), bundle


def test_supersede_links_both_ways_and_every_change_is_audited(
        store_url: str, tmp_path: Path) -> None:
    old, old_bundle = _certificate(store_url, tmp_path / "old")
    new, new_bundle = _certificate(store_url, tmp_path / "new")
    code, out, err = aatest("records", "supersede", old, "--by", new, "--reason",
                            "wrong serial on the certificate", "--records", store_url)
    assert code == 0 and f"certificate {old} superseded by {new}" in out, err
    problems, _ = verify_against_record(old_bundle, store_url)
    assert any(f"{old} was superseded by {new}" in p and "wrong serial" in p for p in problems)
    problems, note = verify_against_record(new_bundle, store_url)
    assert problems == [] and f"it supersedes {old}" in note
    code, _, err = aatest("records", "supersede", old, "--reason", "again", "--records",
                          store_url)
    assert code == 2 and "already superseded" in err
    code, _, err = aatest("records", "supersede", "AUD-2026-999999", "--reason", "x",
                          "--records", store_url)
    assert code == 2 and "never issued" in err
    code, out, _ = aatest("records", "supersede", new, "--reason", "unit scrapped",
                          "--records", store_url)
    assert code == 0 and f"certificate {new} withdrawn: unit scrapped" in out

    code, out, _ = aatest("records", "audit", "--records", store_url)
    assert code == 0, out
    actions = [line.split()[2] for line in out.splitlines()[:-1]]
    assert actions == ["register", "register", "superseded", "withdrawn"]
    assert "audit trail intact: 4 change(s)" in out

    engine = create_engine(resolve_url(store_url))
    with engine.begin() as connection:  # someone softens the reason in SQL
        connection.execute(text("UPDATE audit_log SET reason = 'typo' WHERE action = "
                                "'superseded'"))
    engine.dispose()
    code, out, _ = aatest("records", "audit", "--records", store_url)
    assert code == 1 and "audit trail broken at audit row 3: its content was edited" in out


def test_a_removed_audit_row_breaks_the_link(sqlite_url: str, tmp_path: Path) -> None:
    _certificate(sqlite_url, tmp_path / "a")
    _certificate(sqlite_url, tmp_path / "b")
    engine = create_engine(resolve_url(sqlite_url))
    with engine.begin() as connection:
        connection.execute(text("DELETE FROM audit_log WHERE id = 1"))
    engine.dispose()
    code, out, _ = aatest("records", "audit", "--records", sqlite_url)
    assert code == 1 and "audit row 2: its link to the row before it is broken" in out
