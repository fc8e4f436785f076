"""Schema migrations: a store written by schema version 1 is upgraded with its data kept."""

from __future__ import annotations

import json
from datetime import UTC, datetime

import pytest
from sqlalchemy import text

from aatest.records import schema
from aatest.records.engine import open_engine
from aatest.records.store import RecordStore
from aatest.records.url import resolve_url

RESULTS_V1 = {
    "procedure": "scale-factor",
    "analysis": {
        "scale_factor": {"v_sz": {"scale_v_per_dps2": 0.0040117, "expanded_uncertainty": 8.5e-8}},
        "bias": {"v_sz": {"bias_v": 2.50213, "g_sensitivity_dps2_per_g": 0.41}},
    },
    "signature": {"fingerprint": "f" * 64},
    "metadata": {"sensor": {"model": "sr207", "serial": "OLD1"}},
}


def _write_version_1(url: str) -> None:
    engine = open_engine(resolve_url(url))
    schema.upgrade(engine, "0001")
    assert schema.current_revision(engine) == "0001"
    when = datetime(2025, 6, 1, 8, 0, tzinfo=UTC)
    with engine.begin() as connection:
        connection.execute(text(
            "INSERT INTO units (id, model, serial) VALUES (1, 'sr207', 'OLD1')"))
        connection.execute(text(
            "INSERT INTO certificate_counters (prefix, year, last_number) VALUES ('LAB', 2025, 7)"))
        connection.execute(text(
            "INSERT INTO certificates (number, prefix, year, sequence, issued_utc) "
            "VALUES ('LAB-2025-000007', 'LAB', 2025, 7, :when)"), {"when": when})
        connection.execute(text(
            "INSERT INTO calibrations (id, unit_id, certificate_number, command, procedure, rig,"
            " plugin_versions, lab, calibrated_utc, registered_utc, overall_verdict, verdicts,"
            " results, bundle) VALUES (1, 1, 'LAB-2025-000007', 'run', 'scale-factor', '{}', '{}',"
            " 'Old Lab', :when, :when, 'pass', '[]', :results, '/old/report.html')"),
            {"when": when, "results": json.dumps(RESULTS_V1)})
        connection.execute(text(
            "INSERT INTO signed_files (calibration_id, name, sha256)"
            " VALUES (1, 'report.html', :h)"),
            {"h": "c" * 64})
    engine.dispose()


def test_upgrade_from_version_1_keeps_and_backfills_records(store_url: str) -> None:
    _write_version_1(store_url)
    with RecordStore.open(store_url) as store:  # opening migrates to head
        assert schema.current_revision(store.engine) == schema.head_revision() == "0007"
        (record,) = store.history("OLD1")
        next_number = store.issue_certificate("LAB", datetime(2025, 9, 1, tzinfo=UTC))
    assert record.certificate_number == "LAB-2025-000007"
    assert record.key_fingerprint == "f" * 64
    assert record.files == {"report.html": "c" * 64}
    assert record.quantities["scale_factor.v_sz"].value == pytest.approx(0.0040117)
    assert record.quantities["scale_factor.v_sz"].expanded_uncertainty == pytest.approx(8.5e-8)
    assert record.quantities["g_sensitivity.v_sz"].expanded_uncertainty is None
    assert next_number == "LAB-2025-000008"


def test_opening_a_current_store_twice_is_idempotent(store_url: str) -> None:
    RecordStore.open(store_url).close()
    with RecordStore.open(store_url) as store:
        assert schema.current_revision(store.engine) == schema.head_revision()


def test_upgrade_computes_the_chain_of_existing_records(store_url: str) -> None:
    """A store from before the chain gets it on upgrade; a later SQL edit is then caught."""
    _write_version_1(store_url)
    with RecordStore.open(store_url) as store:
        report = store.check_chain()
        assert report.broken is None and report.count == 1 and len(report.head) == 64
        with store.engine.begin() as connection:
            connection.execute(text("UPDATE quantities SET value = value * 1.05 "
                                    "WHERE calibration_id = 1 AND name = 'scale_factor.v_sz'"))
        broken = store.check_chain().broken
    assert broken is not None and (broken.record_id, broken.certificate_number) == (
        1, "LAB-2025-000007")


def test_upgrade_classifies_old_twin_records_as_simulations(store_url: str) -> None:
    """Migration 0004: a record of the digital twin registered before `kind` existed becomes a
    simulation (out of the history), with the chain recomputed and intact."""
    engine = open_engine(resolve_url(store_url))
    twin = {**RESULTS_V1, "metadata": {**RESULTS_V1["metadata"],  # type: ignore[dict-item]
                                       "rig": {"turntable": {"plugin": "sim"},
                                               "daq": {"plugin": "sim"},
                                               "chamber": {"plugin": "none"}}}}
    _write_version_1(store_url)
    with engine.begin() as connection:
        connection.execute(text("UPDATE calibrations SET results = :r"),
                           {"r": json.dumps(twin)})
    schema.upgrade(engine, "0003")
    with engine.connect() as connection:
        assert connection.execute(text("SELECT row_hash FROM calibrations")).scalar()
    engine.dispose()
    with RecordStore.open(store_url) as store:
        assert store.history("OLD1") == []
        (record,) = store.history("OLD1", include_simulations=True)
        assert record.kind == "simulation"
        assert store.check_chain().broken is None
