"""Certificate numbers: unique and gap-free per lab prefix and year (``LAB-2026-000123``).

The counter row of (prefix, year) is locked for the whole transaction — ``SELECT … FOR UPDATE``
on PostgreSQL, the database write lock taken by ``BEGIN IMMEDIATE`` on SQLite — and the issued
number is inserted into ``certificates`` in the same transaction, so several stations issuing at
once get consecutive numbers and a crash can never leave a hole.
"""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import select
from sqlalchemy.dialects import postgresql, sqlite
from sqlalchemy.engine import Connection

from aatest.records.tables import certificate_counters, certificates

SEQUENCE_DIGITS = 6


def format_number(prefix: str, year: int, sequence: int) -> str:
    """``format_number("LAB", 2026, 123)`` → ``'LAB-2026-000123'``."""
    return f"{prefix}-{year:04d}-{sequence:0{SEQUENCE_DIGITS}d}"


def _ensure_counter(connection: Connection, prefix: str, year: int) -> None:
    dialect = postgresql if connection.dialect.name == "postgresql" else sqlite
    connection.execute(
        dialect.insert(certificate_counters)
        .values(prefix=prefix, year=year, last_number=0)
        .on_conflict_do_nothing(index_elements=["prefix", "year"])
    )


def allocate(connection: Connection, prefix: str, issued_utc: datetime) -> str:
    """Issue the next number of ``prefix`` in the year of ``issued_utc`` (inside a transaction).

    The caller owns the transaction; on SQLite it must have been begun with ``BEGIN IMMEDIATE``
    (:mod:`aatest.records.engine` does so for every transaction).
    """
    year = issued_utc.year
    _ensure_counter(connection, prefix, year)
    key = (certificate_counters.c.prefix == prefix) & (certificate_counters.c.year == year)
    last = connection.execute(
        select(certificate_counters.c.last_number).where(key).with_for_update()
    ).scalar_one()
    sequence = int(last) + 1
    connection.execute(certificate_counters.update().where(key).values(last_number=sequence))
    number = format_number(prefix, year, sequence)
    connection.execute(certificates.insert().values(
        number=number, prefix=prefix, year=year, sequence=sequence, issued_utc=issued_utc))
    return number
