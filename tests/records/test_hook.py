"""The bundle observer numbers the typed results and states the issuing lab in them."""

from __future__ import annotations

from pathlib import Path

from aatest.engine.run import bundle_hooks
from aatest.records.hook import registering
from aatest.records.lab import LabProfile
from aatest.results import RunResults


def test_results_get_consecutive_numbers_and_the_lab(sqlite_url: str) -> None:
    first, second = RunResults(procedure="scale-factor"), RunResults(procedure="scale-factor")
    with registering(sqlite_url, LabProfile(certificate_prefix="TY"), "run"):
        bundle_hooks.before_signing(first)
        bundle_hooks.before_signing(second)
    assert first.certificate_number is not None and first.certificate_number.endswith("-000001")
    assert second.certificate_number is not None
    assert second.certificate_number.endswith("-000002")
    assert first.metadata.lab is not None and first.metadata.lab["name"] == "aatest lab"
    assert "lab" in first.model_dump(mode="json")["metadata"]


def test_report_keeps_the_number_and_outside_a_scope_nothing_happens(
        sqlite_url: str, tmp_path: Path) -> None:
    kept = RunResults(procedure="scale-factor", certificate_number="TY-2026-000042")
    with registering(sqlite_url, LabProfile(certificate_prefix="TY"), "report"):
        bundle_hooks.before_signing(kept)
    assert kept.certificate_number == "TY-2026-000042"
    untouched = RunResults(procedure="scale-factor")
    bundle_hooks.before_signing(untouched)
    bundle_hooks.after_signing(untouched, tmp_path / "report.html")
    assert untouched == RunResults(procedure="scale-factor")
