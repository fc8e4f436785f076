"""The store on both engines: append-only registration, supersession, queries, URLs, errors."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest

from aatest.records.errors import RecordsError, RecordsUnavailable
from aatest.records.models import QuantityRecord, RecordFilter, Registration
from aatest.records.store import RecordStore
from aatest.records.url import redacted, resolve_url

T0 = datetime(2026, 3, 1, 9, 30, tzinfo=UTC)


def _registration(serial: str, bundle: str, day: int, scale: float,
                  **extra: object) -> Registration:
    fields: dict[str, object] = dict(
        model="sr207", serial=serial, command="run", procedure="scale-factor", lab="Test Lab",
        calibrated_utc=T0 + timedelta(days=day), bundle=bundle, overall_verdict="pass",
        files={"report.html": "a" * 64, "recording.mcap": "b" * 64},
        quantities={"scale_factor.v_sz": QuantityRecord(
            value=scale, expanded_uncertainty=2e-7, unit="V/(°/s²)")})
    fields.update(extra)
    return Registration(**fields)  # type: ignore[arg-type]


def test_register_and_history_oldest_first(store_url: str) -> None:
    with RecordStore.open(store_url) as store:
        store.register(_registration("A1", "/runs/2/report.html", 30, 0.004012))
        store.register(_registration("A1", "/runs/1/report.html", 0, 0.004011))
        store.register(_registration("B2", "/runs/3/report.html", 5, 0.004020))
        history = store.history("A1")
    assert [r.bundle for r in history] == ["/runs/1/report.html", "/runs/2/report.html"]
    assert history[0].calibrated_utc == T0
    assert history[0].quantities["scale_factor.v_sz"].expanded_uncertainty == pytest.approx(2e-7)
    assert history[0].files == {"report.html": "a" * 64, "recording.mcap": "b" * 64}


def test_reregistering_a_bundle_supersedes_without_changing_the_old_record(store_url: str) -> None:
    with RecordStore.open(store_url) as store:
        first = store.register(_registration("A1", "/runs/1/report.html", 0, 0.004011,
                                              certificate_number=None))
        second = store.register(_registration("A1", "/runs/1/report.html", 0, 0.004013,
                                               command="analyze"))
        current = store.history("A1")
        everything = store.query(RecordFilter(serial="A1", include_superseded=True))
    assert [r.id for r in current] == [second]
    assert current[0].supersedes_id == first
    old = next(r for r in everything if r.id == first)
    assert old.superseded_by == second
    assert old.quantities["scale_factor.v_sz"].value == pytest.approx(0.004011)


def test_query_filters(store_url: str) -> None:
    with RecordStore.open(store_url) as store:
        store.register(_registration("A1", "/r/1/report.html", 0, 1.0))
        store.register(_registration("A1", "/r/2/report.html", 10, 1.0, overall_verdict="fail"))
        store.register(_registration("C3", "/r/3/report.html", 20, 1.0, model="sr207-aamu",
                                     procedure="frf"))
        by_verdict = store.query(RecordFilter(verdict="fail"))
        by_model = store.query(RecordFilter(model="sr207-aamu"))
        by_dates = store.query(RecordFilter(since_utc=T0 + timedelta(days=5),
                                            until_utc=T0 + timedelta(days=15)))
        by_procedure = store.query(RecordFilter(procedure="scale-factor"))
    assert [r.bundle for r in by_verdict] == ["/r/2/report.html"]
    assert [r.serial for r in by_model] == ["C3"]
    assert [r.bundle for r in by_dates] == ["/r/2/report.html"]
    assert len(by_procedure) == 2


def test_get_by_certificate_number(store_url: str) -> None:
    with RecordStore.open(store_url) as store:
        number = store.issue_certificate("LAB", T0)
        store.register(_registration("A1", "/r/1/report.html", 0, 1.0, certificate_number=number))
        assert store.get(number).certificate_number == "LAB-2026-000001"
        with pytest.raises(RecordsError, match="no record 'LAB-2026-000009'"):
            store.get("LAB-2026-000009")


def test_plain_postgres_url_uses_psycopg3_and_hides_the_password() -> None:
    url = resolve_url("postgresql://cal:s3cret@db.lab:5433/records")
    assert url.drivername == "postgresql+psycopg"
    assert redacted(url) == "postgresql+psycopg://cal:***@db.lab:5433/records"


@pytest.mark.parametrize("text", ["mysql://u@h/db", "not a url"], ids=["mysql", "garbage"])
def test_unsupported_urls_are_bad_input(text: str) -> None:
    with pytest.raises(RecordsError) as caught:
        resolve_url(text)
    assert caught.value.exit_code == 2


def test_unreachable_database_names_the_url_without_password() -> None:
    with pytest.raises(RecordsUnavailable) as caught:
        RecordStore.open("postgresql://cal:s3cret@127.0.0.1:9/records")
    message = str(caught.value)
    assert "postgresql+psycopg://cal:***@127.0.0.1:9/records" in message
    assert "s3cret" not in message
    assert caught.value.exit_code == 2 and isinstance(caught.value, ConnectionError)


def test_environment_then_default(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("AATEST_RECORDS", "sqlite:///from-env.sqlite")
    assert resolve_url().database == "from-env.sqlite"
    assert resolve_url("sqlite:///explicit.sqlite").database == "explicit.sqlite"
    monkeypatch.delenv("AATEST_RECORDS")
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path))
    assert resolve_url().database == str(tmp_path / "aatest" / "records.sqlite")
