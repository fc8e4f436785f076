"""Per-rig recurrence of diagnosed effects: the rig's, one unit's, or undecided."""

from __future__ import annotations

import json
from datetime import UTC, datetime
from pathlib import Path

from aatest.fleet.analysis import fleet_diagnoses
from aatest.fleet.archive import FleetRecord, stored_findings
from aatest.fleet.recurrence import RIG, UNDECIDED, UNIT, UnitDiagnosis, classify, summarise
from aatest.records.models import CalibrationRecord

WHEN = datetime(2026, 1, 1, tzinfo=UTC)


def _unit(serial: str, rig: str, *effects: str) -> UnitDiagnosis:
    return UnitDiagnosis(serial, "sr207", rig, frozenset(effects), "test")


def test_classification_thresholds() -> None:
    # two of four units: half the rig and two units → the rig's; one of two: one unit only
    assert classify(2, 4) == RIG
    assert classify(1, 2) == UNIT
    assert classify(2, 5) == UNIT  # 40 % of the rig's units
    assert classify(1, 1) == UNDECIDED


def test_summary_counts_units_not_diagnoses() -> None:
    found = summarise([_unit("A", "T1", "rate_ripple"), _unit("A", "T1", "rate_ripple"),
                       _unit("B", "T1"), _unit("C", "T1", "rate_ripple", "time_delay"),
                       _unit("D", "T2", "time_delay"),
                       UnitDiagnosis("E", "sr207", "T2", None, "not diagnosed")])
    t1, t2 = found
    assert t1.diagnosed == ("A", "B", "C")
    assert [(e.effect, e.units, e.classification) for e in t1.effects] == [
        ("rate_ripple", ("A", "C"), RIG), ("time_delay", ("C",), UNIT)]
    assert t2.undiagnosed == ("E",)
    assert [(e.effect, e.classification) for e in t2.effects] == [("time_delay", UNDECIDED)]


def _record(bundle: Path, command: str) -> CalibrationRecord:
    return CalibrationRecord(
        id=1, model="sr207", serial="S1", certificate_number=None, supersedes_id=None,
        superseded_by=None, command=command, procedure="p", procedure_sha256=None, operator=None,
        lab="L", calibrated_utc=WHEN, registered_utc=WHEN, overall_verdict="none", verdicts=[],
        bundle=str(bundle), key_fingerprint=None, files={}, quantities={}, rig={},
        plugin_versions={})


def test_findings_are_read_from_the_json_beside_a_registered_report(tmp_path: Path) -> None:
    report = tmp_path / "diagnosis.html"
    report.write_text("<html></html>")
    assert stored_findings(_record(report, "diagnose")) is None  # nothing readable yet
    (tmp_path / "diagnosis.json").write_text(json.dumps(
        {"findings": [{"effect": "rate_ripple", "channel": "v_sz"}]}))
    assert stored_findings(_record(report, "diagnose")) == [
        {"effect": "rate_ripple", "channel": "v_sz"}]


def test_units_without_findings_are_diagnosed_on_demand_or_named(tmp_path: Path) -> None:
    rows = [FleetRecord(_record(tmp_path / "report.html", "run"), "T1")]
    (named,) = fleet_diagnoses(rows, None)
    assert named.effects is None and named.source == "not diagnosed"
    (diagnosed,) = fleet_diagnoses(rows, lambda f: [{"effect": "time_delay"}])
    assert diagnosed.effects == frozenset({"time_delay"})
