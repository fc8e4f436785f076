"""The bundle observer numbers typed results as well as plain ``results.json`` dicts."""

from __future__ import annotations

from pathlib import Path

from pydantic import BaseModel, ConfigDict

from aatest.engine.run import bundle_hooks
from aatest.records.hook import registering
from aatest.records.lab import LabProfile


class _TypedResults(BaseModel):
    """Stands in for the typed ``RunResults`` root: strict, with ``certificate_number``."""

    model_config = ConfigDict(extra="forbid", validate_assignment=True)
    procedure: str = "scale-factor"
    certificate_number: str | None = None


def test_typed_and_plain_results_get_consecutive_numbers(sqlite_url: str) -> None:
    typed, plain = _TypedResults(), {"procedure": "scale-factor"}
    with registering(sqlite_url, LabProfile(certificate_prefix="TY"), "run"):
        bundle_hooks.before_signing(typed)
        bundle_hooks.before_signing(plain)
    assert typed.certificate_number is not None and typed.certificate_number.endswith("-000001")
    assert plain["certificate_number"].endswith("-000002")


def test_report_keeps_the_number_and_outside_a_scope_nothing_happens(
        sqlite_url: str, tmp_path: Path) -> None:
    kept = _TypedResults(certificate_number="TY-2026-000042")
    with registering(sqlite_url, LabProfile(certificate_prefix="TY"), "report"):
        bundle_hooks.before_signing(kept)
    assert kept.certificate_number == "TY-2026-000042"
    untouched: dict[str, str] = {}
    bundle_hooks.before_signing(untouched)
    bundle_hooks.after_signing(untouched, tmp_path / "report.html")
    assert untouched == {}
