"""The bundle observer numbers typed results as well as plain ``results.json`` dicts."""

from __future__ import annotations

from pathlib import Path

from pydantic import BaseModel, ConfigDict

from aatest.engine.run import bundle_hooks
from aatest.records.hook import registering
from aatest.records.lab import LabProfile
from aatest.records.models import RecordFilter
from aatest.records.store import RecordStore


class _TypedResults(BaseModel):
    """Stands in for the typed ``RunResults`` root: strict, with ``certificate_number``."""

    model_config = ConfigDict(extra="forbid", validate_assignment=True)
    procedure: str = "scale-factor"
    certificate_number: str | None = None


def _bundle(folder: Path) -> Path:
    folder.mkdir()
    (folder / "report.html").write_text("<html>signed</html>")
    return folder / "report.html"


def test_typed_and_plain_results_get_consecutive_numbers(sqlite_url: str, tmp_path: Path) -> None:
    typed, plain = _TypedResults(), {"procedure": "scale-factor"}
    with registering(sqlite_url, LabProfile(certificate_prefix="TY"), "run"):
        bundle_hooks.before_signing(typed)
        bundle_hooks.after_signing(typed, _bundle(tmp_path / "a"))
        bundle_hooks.before_signing(plain)
        bundle_hooks.after_signing(plain, _bundle(tmp_path / "b"))
    assert typed.certificate_number is not None and typed.certificate_number.endswith("-000001")
    assert plain["certificate_number"].endswith("-000002")


def test_a_number_never_registered_is_rolled_back(sqlite_url: str, tmp_path: Path) -> None:
    """A bundle that never reached registration leaves no number: the next one takes it."""
    abandoned, kept = {"procedure": "scale-factor"}, {"procedure": "scale-factor"}
    with registering(sqlite_url, LabProfile(certificate_prefix="TY"), "run"):
        bundle_hooks.before_signing(abandoned)  # e.g. the report failed after this
    with registering(sqlite_url, LabProfile(certificate_prefix="TY"), "run"):
        bundle_hooks.before_signing(kept)
        bundle_hooks.after_signing(kept, _bundle(tmp_path / "kept"))
    assert abandoned["certificate_number"] == kept["certificate_number"]
    with RecordStore.open(sqlite_url) as store:
        assert store.certificate_issued(kept["certificate_number"])
        assert len(store.query(RecordFilter())) == 1


def test_report_keeps_the_number_and_outside_a_scope_nothing_happens(
        sqlite_url: str, tmp_path: Path) -> None:
    issued = _TypedResults()
    with registering(sqlite_url, LabProfile(certificate_prefix="TY"), "run"):
        bundle_hooks.before_signing(issued)
        bundle_hooks.after_signing(issued, _bundle(tmp_path / "run"))
    kept = _TypedResults(certificate_number=issued.certificate_number)
    with registering(sqlite_url, LabProfile(certificate_prefix="TY"), "report"):
        bundle_hooks.before_signing(kept)
    assert kept.certificate_number == issued.certificate_number
    never = _TypedResults(certificate_number="TY-2026-000042")  # stated, never issued
    with registering(sqlite_url, LabProfile(certificate_prefix="TY"), "report"):
        bundle_hooks.before_signing(never)
    # re-signing numbers it properly
    assert never.certificate_number == f"{issued.certificate_number[:-6]}000002"
    untouched: dict[str, str] = {}
    bundle_hooks.before_signing(untouched)
    bundle_hooks.after_signing(untouched, tmp_path / "report.html")
    assert untouched == {}
