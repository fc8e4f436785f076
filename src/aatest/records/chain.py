"""A hash chain over the calibration records: an edit in the database shows.

Every ``calibrations`` row stores ``previous_hash`` (the ``row_hash`` of the row before it in id
order, :data:`GENESIS` for the first) and ``row_hash`` = SHA-256 of the previous hash and the
canonical JSON of the record's content — its own columns, the unit's model and serial, its
signed-file hashes and its key quantities with their expanded uncertainties. Changing a verdict,
a value or a U directly in SQL breaks that row's hash; recomputing the hash breaks the next
row's link; deleting a row breaks its successor's link. :func:`check` walks the chain and names
the first broken row (``aatest records check``); :func:`record_problems` checks the links that
vouch for one record (``aatest verify``).

What a chain cannot show by itself: rows appended at the end by someone writing the database
directly with correctly computed hashes, or the newest rows removed. Keeping the head hash
``records check`` prints elsewhere (a log, a printed certificate register) closes that gap.
"""

from __future__ import annotations

import hashlib
import json
from collections import defaultdict
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

from sqlalchemy import Select, select, text
from sqlalchemy.engine import Connection, Row

from aatest.records.tables import calibrations, quantities, signed_files, units

CHAIN_FORMAT = "aatest-records-chain/1"
GENESIS = "0" * 64
#: advisory-lock key that serialises appends to the chain on PostgreSQL (unique to aatest)
_LOCK_KEY = 0x6161_7465_7374_0001
_BATCH = 500
#: the ``kind`` every record had before migration 0004 (left out of the hashed content)
CALIBRATION_KIND = "calibration"
#: the record's own columns the hash covers (explicit: a later column changes no old hash)
CONTENT_COLUMNS: tuple[str, ...] = (
    "id", "certificate_number", "supersedes_id", "command", "procedure", "procedure_sha256",
    "rig", "plugin_versions", "operator", "lab", "calibrated_utc", "registered_utc",
    "overall_verdict", "verdicts", "results", "bundle", "key_fingerprint")


@dataclass(frozen=True)
class ChainBreak:
    """The first row whose hash or link does not hold, and why."""

    record_id: int
    certificate_number: str | None
    reason: str

    def describe(self) -> str:
        """``record 7 (LAB-2026-000003): …``, as printed."""
        label = f" ({self.certificate_number})" if self.certificate_number else ""
        return f"record {self.record_id}{label}: {self.reason}"


@dataclass(frozen=True)
class ChainReport:
    """Outcome of :func:`check`: how many rows were walked, the head hash, the first break."""

    count: int
    head: str
    broken: ChainBreak | None


def _utc_text(moment: datetime) -> str:
    aware = moment.replace(tzinfo=UTC) if moment.tzinfo is None else moment.astimezone(UTC)
    return aware.isoformat(timespec="microseconds")


def _canonical(value: Any) -> Any:
    if isinstance(value, datetime):
        return _utc_text(value)
    return value


def row_digest(previous: str, content: dict[str, Any]) -> str:
    """SHA-256 hex of ``previous`` and the canonical JSON of ``content`` (sorted keys)."""
    body = json.dumps({"chain": CHAIN_FORMAT, **content}, sort_keys=True,
                      separators=(",", ":"), ensure_ascii=False, default=str)
    return hashlib.sha256(previous.encode("ascii") + b"\n" + body.encode("utf-8")).hexdigest()


def _rows(connection: Connection, query: Select[Any]) -> list[Row[Any]]:
    return list(connection.execute(query).all())


def _content_query(with_kind: bool = True) -> Select[Any]:
    """The hashed columns; ``with_kind=False`` for a schema before migration 0004."""
    columns = [calibrations.c[name] for name in CONTENT_COLUMNS]
    if with_kind:
        columns.append(calibrations.c.kind)
    return (select(*columns, calibrations.c.previous_hash, calibrations.c.row_hash,
                   units.c.model, units.c.serial)
            .join(units, units.c.id == calibrations.c.unit_id)
            .order_by(calibrations.c.id))


def _contents(connection: Connection, rows: Sequence[Row[Any]]) -> list[dict[str, Any]]:
    """The hashed content of each of ``rows`` (a :func:`_content_query` result), children too."""
    ids = [row.id for row in rows]
    files: dict[int, list[list[str]]] = defaultdict(list)
    values: dict[int, list[list[Any]]] = defaultdict(list)
    for f in connection.execute(select(signed_files).where(signed_files.c.calibration_id.in_(ids))
                                .order_by(signed_files.c.name)):
        files[f.calibration_id].append([f.name, f.sha256])
    for q in connection.execute(select(quantities).where(quantities.c.calibration_id.in_(ids))
                                .order_by(quantities.c.name)):
        values[q.calibration_id].append([q.name, q.value, q.expanded_uncertainty, q.unit])
    out = []
    for row in rows:
        content = {name: _canonical(getattr(row, name)) for name in CONTENT_COLUMNS}
        kind = getattr(row, "kind", CALIBRATION_KIND)
        if kind != CALIBRATION_KIND:  # hashed when not the default: no calibration's hash changes
            content["kind"] = kind
        content.update(model=row.model, serial=row.serial, files=files.get(row.id, []),
                       quantities=values.get(row.id, []))
        out.append(content)
    return out


def lock(connection: Connection) -> None:
    """Serialise appends (PostgreSQL; SQLite's ``BEGIN IMMEDIATE`` already does)."""
    if connection.dialect.name == "postgresql":
        connection.execute(text("SELECT pg_advisory_xact_lock(:key)"), {"key": _LOCK_KEY})


def _previous_hash(connection: Connection, record_id: int) -> str:
    before = connection.execute(select(calibrations.c.row_hash).where(
        calibrations.c.id < record_id).order_by(calibrations.c.id.desc()).limit(1)).first()
    return GENESIS if before is None or before.row_hash is None else str(before.row_hash)


def digest_of(connection: Connection, record_id: int, previous: str,
              with_kind: bool = True) -> str:
    """The row hash record ``record_id`` has, as stored now, when it follows ``previous``."""
    rows = _rows(connection, _content_query(with_kind).where(calibrations.c.id == record_id))
    return row_digest(previous, _contents(connection, rows)[0])


def append(connection: Connection, record_id: int, with_kind: bool = True) -> str:
    """Hash the just-inserted record ``record_id`` onto the chain (inside its transaction).

    The content is read back from the database, so the hash is of exactly what is stored; the
    caller holds :func:`lock`. Returns the new row hash.
    """
    previous = _previous_hash(connection, record_id)
    digest = digest_of(connection, record_id, previous, with_kind)
    connection.execute(calibrations.update().where(calibrations.c.id == record_id)
                       .values(previous_hash=previous, row_hash=digest))
    return digest


def _batches(connection: Connection, start_id: int | None, limit: int | None,
             with_kind: bool = True) -> Iterator[list[Row[Any]]]:
    after = -1 if start_id is None else start_id - 1
    remaining = limit
    while remaining is None or remaining > 0:
        size = _BATCH if remaining is None else min(_BATCH, remaining)
        rows = _rows(connection, _content_query(with_kind).where(calibrations.c.id > after)
                     .limit(size))
        if not rows:
            return
        yield rows
        after = rows[-1].id
        remaining = None if remaining is None else remaining - len(rows)


def _break_of(row: Row[Any], previous: str, content: dict[str, Any]) -> ChainBreak | None:
    if row.row_hash is None or row.previous_hash is None:
        reason = "has no chain hash (written past aatest, or by a version without the chain)"
    elif row.previous_hash != previous:
        reason = ("its link to the record before it is broken: that record was re-hashed, or "
                  "a record between them was removed")
    elif row_digest(previous, content) != row.row_hash:
        reason = ("its content differs from what was hashed when it was registered (e.g. its "
                  "verdict, a value, an uncertainty, a file hash or its unit was edited)")
    else:
        return None
    return ChainBreak(int(row.id), row.certificate_number, reason)


def check(connection: Connection, start_id: int | None = None,
          limit: int | None = None) -> ChainReport:
    """Recompute the chain from ``start_id`` (default: the first row) for ``limit`` rows.

    Stops at the first broken row. ``head`` is the last row hash walked (the chain's head when
    the whole chain was checked).
    """
    previous = GENESIS if start_id is None else _previous_hash(connection, start_id)
    count = 0
    for rows in _batches(connection, start_id, limit):
        for row, content in zip(rows, _contents(connection, rows), strict=True):
            broken = _break_of(row, previous, content)
            if broken is not None:
                return ChainReport(count, previous, broken)
            previous = str(row.row_hash)
            count += 1
    return ChainReport(count, previous, None)


def record_problems(connection: Connection, record_id: int) -> list[str]:
    """The chain links that vouch for record ``record_id``: its own, and its successor's."""
    report = check(connection, record_id, limit=1)
    if report.broken is not None:
        return [f"records chain broken at {report.broken.describe()}"]
    successor = connection.execute(
        select(calibrations.c.id, calibrations.c.certificate_number, calibrations.c.previous_hash)
        .where(calibrations.c.id > record_id).order_by(calibrations.c.id).limit(1)).first()
    if successor is not None and successor.previous_hash != report.head:
        label = ChainBreak(int(successor.id), successor.certificate_number,
                           f"its link to record {record_id} is broken: record {record_id} was "
                           "edited and re-hashed").describe()
        return [f"records chain broken at {label}"]
    return []


def rehash_all(connection: Connection, with_kind: bool = True) -> int:
    """Compute the chain over every existing row, oldest first (the migrations that change
    what is hashed; ``with_kind=False`` before the ``kind`` column exists)."""
    count = 0
    for rows in _batches(connection, None, None, with_kind):
        for row in rows:
            append(connection, int(row.id), with_kind)
            count += 1
    return count
