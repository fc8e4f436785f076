"""The bundle observer numbers the typed results, only for bundles it registers."""

from __future__ import annotations

from pathlib import Path

from aatest.bundle import observers as bundle_observers
from aatest.records.hook import registering
from aatest.records.lab import LabProfile
from aatest.records.models import RecordFilter
from aatest.records.store import RecordStore
from aatest.results import RunResults


def _bundle(folder: Path) -> Path:
    folder.mkdir()
    (folder / "report.html").write_text("<html>signed</html>")
    return folder / "report.html"


def test_results_get_consecutive_numbers_and_the_lab(sqlite_url: str, tmp_path: Path) -> None:
    first, second = RunResults(procedure="scale-factor"), RunResults(procedure="scale-factor")
    with registering(sqlite_url, LabProfile(certificate_prefix="TY"), "run"):
        bundle_observers.before_signing(first)
        bundle_observers.after_signing(first, _bundle(tmp_path / "a"))
        bundle_observers.before_signing(second)
        bundle_observers.after_signing(second, _bundle(tmp_path / "b"))
    assert first.certificate_number is not None and first.certificate_number.endswith("-000001")
    assert second.certificate_number is not None
    assert second.certificate_number.endswith("-000002")
    assert first.metadata.lab is not None and first.metadata.lab["name"] == "aatest lab"
    assert "lab" in first.model_dump(mode="json")["metadata"]


def test_a_number_never_registered_is_rolled_back(sqlite_url: str, tmp_path: Path) -> None:
    """A bundle that never reached registration leaves no number: the next one takes it."""
    abandoned, kept = RunResults(procedure="scale-factor"), RunResults(procedure="scale-factor")
    with registering(sqlite_url, LabProfile(certificate_prefix="TY"), "run"):
        bundle_observers.before_signing(abandoned)  # e.g. the report failed after this
    with registering(sqlite_url, LabProfile(certificate_prefix="TY"), "run"):
        bundle_observers.before_signing(kept)
        bundle_observers.after_signing(kept, _bundle(tmp_path / "kept"))
    assert kept.certificate_number is not None
    assert abandoned.certificate_number == kept.certificate_number
    with RecordStore.open(sqlite_url) as store:
        assert store.certificate_issued(kept.certificate_number)
        assert len(store.query(RecordFilter())) == 1


def test_report_keeps_the_number_and_outside_a_scope_nothing_happens(
        sqlite_url: str, tmp_path: Path) -> None:
    issued = RunResults(procedure="scale-factor")
    with registering(sqlite_url, LabProfile(certificate_prefix="TY"), "run"):
        bundle_observers.before_signing(issued)
        bundle_observers.after_signing(issued, _bundle(tmp_path / "run"))
    assert issued.certificate_number is not None
    kept = RunResults(procedure="scale-factor", certificate_number=issued.certificate_number)
    with registering(sqlite_url, LabProfile(certificate_prefix="TY"), "report"):
        bundle_observers.before_signing(kept)
    assert kept.certificate_number == issued.certificate_number
    never = RunResults(procedure="scale-factor", certificate_number="TY-2026-000042")
    with registering(sqlite_url, LabProfile(certificate_prefix="TY"), "report"):
        bundle_observers.before_signing(never)  # stated, never issued: re-signing numbers it
    assert never.certificate_number == f"{issued.certificate_number[:-6]}000002"
    untouched = RunResults(procedure="scale-factor")
    bundle_observers.before_signing(untouched)
    bundle_observers.after_signing(untouched, tmp_path / "report.html")
    assert untouched == RunResults(procedure="scale-factor")
