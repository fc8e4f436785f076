"""Certificate numbers: unique, consecutive and gap-free, also with several stations at once."""

from __future__ import annotations

import multiprocessing
from datetime import UTC, datetime

import pytest
from sqlalchemy import select

from aatest.records.numbering import format_number
from aatest.records.store import RecordStore
from aatest.records.tables import certificates


def test_format_number() -> None:
    assert format_number("LAB", 2026, 123) == "LAB-2026-000123"


def test_numbers_restart_per_prefix_and_year(store_url: str) -> None:
    with RecordStore.open(store_url) as store:
        jan = datetime(2026, 1, 2, tzinfo=UTC)
        issued = [store.issue_certificate("LAB", jan), store.issue_certificate("LAB", jan),
                  store.issue_certificate("CAL", jan),
                  store.issue_certificate("LAB", datetime(2027, 1, 1, tzinfo=UTC))]
    assert issued == ["LAB-2026-000001", "LAB-2026-000002", "CAL-2026-000001", "LAB-2027-000001"]


def _station(url: str, count: int, barrier: object, queue: object) -> None:
    """One station: open the store, wait for the others, issue ``count`` numbers."""
    with RecordStore.open(url) as store:
        barrier.wait()  # type: ignore[attr-defined]
        numbers = [store.issue_certificate("LAB") for _ in range(count)]
    queue.put(numbers)  # type: ignore[attr-defined]


def _issue_concurrently(url: str, stations: int, each: int) -> list[str]:
    """Every station opens the new, empty store itself: migration and numbering both race."""
    context = multiprocessing.get_context("spawn")
    barrier, queue = context.Barrier(stations), context.Queue()
    workers = [context.Process(target=_station, args=(url, each, barrier, queue))
               for _ in range(stations)]
    for worker in workers:
        worker.start()
    issued = [n for _ in workers for n in queue.get(timeout=300)]
    for worker in workers:
        worker.join(timeout=60)
        assert worker.exitcode == 0
    return issued


def _assert_consecutive(url: str, issued: list[str], total: int) -> None:
    year = datetime.now(UTC).year
    assert len(issued) == total
    assert sorted(issued) == [format_number("LAB", year, n) for n in range(1, total + 1)]
    with RecordStore.open(url) as store, store.engine.connect() as connection:
        sequence = connection.execute(select(certificates.c.sequence).where(
            certificates.c.prefix == "LAB").order_by(certificates.c.sequence)).scalars().all()
    assert sequence == list(range(1, total + 1))


def test_two_stations_on_sqlite_get_100_consecutive_numbers(sqlite_url: str) -> None:
    _assert_consecutive(sqlite_url, _issue_concurrently(sqlite_url, 2, 50), 100)


def test_four_stations_on_postgresql_get_200_consecutive_numbers(postgres_url: str) -> None:
    _assert_consecutive(postgres_url, _issue_concurrently(postgres_url, 4, 50), 200)


@pytest.mark.parametrize("prefix", ["lab", "LAB-1", ""], ids=["lower", "dash", "empty"])
def test_lab_prefix_is_validated(prefix: str) -> None:
    from pydantic import ValidationError

    from aatest.records.lab import LabProfile

    with pytest.raises(ValidationError):
        LabProfile(certificate_prefix=prefix)
