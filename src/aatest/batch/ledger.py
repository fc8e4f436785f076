"""The ``reanalyses`` table: what a batch found, one row per (subject, method), hash-chained.

A re-analysis is never written into the record it re-evaluates (an issued certificate stays
what it was); it is a row of its own that names the record (``record_id``) or, for a recording
selected by URL prefix without a record, the recording itself (``subject``). Rows are only
inserted. Like the calibration records and the audit log, each row stores ``previous_hash``
and ``row_hash`` = SHA-256 over the previous hash and the row's canonical JSON
(:func:`aatest.records.chain.row_digest`), so an edit in SQL shows in :func:`check`.

Why unique on (subject, method hash): a batch that is re-run — after a crash, a killed
worker, or on purpose — skips every recording already re-analysed with the same method, and
two batches racing on one store cannot both insert the same result.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

from sqlalchemy import (
    JSON,
    Column,
    DateTime,
    ForeignKey,
    Integer,
    String,
    Table,
    Text,
    UniqueConstraint,
    select,
)

from aatest.records import chain
from aatest.records.store import RecordStore, as_utc
from aatest.records.tables import metadata

REANALYSIS_FORMAT = "aatest-reanalysis/1"

reanalyses = Table(
    "reanalyses", metadata,
    Column("id", Integer, primary_key=True),
    Column("subject", String(512), nullable=False),
    Column("record_id", Integer, ForeignKey("calibrations.id"), index=True),
    Column("recording", Text, nullable=False),
    Column("mode", String(16), nullable=False),  # analyze | diagnose
    Column("method_hash", String(64), nullable=False),
    Column("method", JSON, nullable=False),
    Column("aatest_version", String(64), nullable=False),
    Column("analysed_utc", DateTime(timezone=True), nullable=False),
    Column("overall_verdict", String(24), nullable=False),
    Column("verdicts", JSON, nullable=False),
    Column("quantities", JSON, nullable=False),
    Column("outcome", JSON, nullable=False),
    Column("previous_hash", String(64), nullable=False),
    Column("row_hash", String(64), nullable=False),
    UniqueConstraint("subject", "method_hash", name="uq_reanalyses_subject_method"),
)

#: the columns the row hash covers
_CONTENT = ("id", "subject", "record_id", "recording", "mode", "method_hash", "method",
            "aatest_version", "analysed_utc", "overall_verdict", "verdicts", "quantities",
            "outcome")


@dataclass(frozen=True)
class Reanalysis:
    """One stored re-analysis (what :func:`stored` returns)."""

    id: int
    subject: str
    record_id: int | None
    recording: str
    mode: str
    method_hash: str
    aatest_version: str
    analysed_utc: datetime
    overall_verdict: str
    verdicts: list[dict[str, Any]]
    quantities: dict[str, dict[str, Any]]
    outcome: dict[str, Any]


def _content(row: Any) -> dict[str, Any]:
    content = {name: getattr(row, name) for name in _CONTENT}
    content["analysed_utc"] = chain._utc_text(row.analysed_utc)
    return {"reanalysis": REANALYSIS_FORMAT, **content}


def append(store: RecordStore, values: dict[str, Any]) -> int | None:
    """Insert one re-analysis and hash it onto the chain, in one transaction.

    Returns the new row id, or ``None`` when (subject, method hash) is stored already (a
    concurrent or repeated batch got there first: nothing is written twice).
    """
    with store.engine.begin() as connection:
        chain.lock(connection)
        if connection.execute(select(reanalyses.c.id).where(
                (reanalyses.c.subject == values["subject"])
                & (reanalyses.c.method_hash == values["method_hash"]))).first() is not None:
            return None
        last = connection.execute(select(reanalyses.c.row_hash).order_by(
            reanalyses.c.id.desc()).limit(1)).scalar()
        previous = str(last) if last else chain.GENESIS
        row_id = connection.execute(reanalyses.insert().values(
            **values, analysed_utc=datetime.now(UTC), previous_hash=previous, row_hash="")
            .returning(reanalyses.c.id)).scalar_one()
        row = connection.execute(select(reanalyses).where(reanalyses.c.id == row_id)).one()
        connection.execute(reanalyses.update().where(reanalyses.c.id == row_id).values(
            row_hash=chain.row_digest(previous, _content(row))))
    return int(row_id)


def done_subjects(store: RecordStore, method_hash: str, subjects: Iterable[str]) -> set[str]:
    """Which of ``subjects`` are re-analysed with ``method_hash`` already."""
    wanted = list(subjects)
    found: set[str] = set()
    with store.engine.connect() as connection:
        for start in range(0, len(wanted), 500):  # bounded IN lists on every engine
            found.update(connection.execute(select(reanalyses.c.subject).where(
                (reanalyses.c.method_hash == method_hash)
                & reanalyses.c.subject.in_(wanted[start:start + 500]))).scalars())
    return found


def stored(store: RecordStore, method_hash: str | None = None) -> list[Reanalysis]:
    """The stored re-analyses (of one method when given), oldest first."""
    query = select(reanalyses).order_by(reanalyses.c.id)
    if method_hash is not None:
        query = query.where(reanalyses.c.method_hash == method_hash)
    with store.engine.connect() as connection:
        rows = connection.execute(query).all()
    return [Reanalysis(
        id=int(r.id), subject=r.subject, record_id=r.record_id, recording=r.recording,
        mode=r.mode, method_hash=r.method_hash, aatest_version=r.aatest_version,
        analysed_utc=as_utc(r.analysed_utc), overall_verdict=r.overall_verdict,
        verdicts=list(r.verdicts), quantities=dict(r.quantities), outcome=dict(r.outcome))
        for r in rows]


def check(store: RecordStore) -> str | None:
    """Walk the re-analysis chain; the first broken row described, or ``None`` when intact."""
    previous = chain.GENESIS
    with store.engine.connect() as connection:
        rows = connection.execute(select(reanalyses).order_by(reanalyses.c.id)).all()
    return _first_break(rows, previous)


def _first_break(rows: Iterable[Any], previous: str) -> str | None:
    for row in rows:
        if row.previous_hash != previous:
            return (f"re-analysis {row.id}: its link to the row before it is broken (that row "
                    "was re-hashed or removed)")
        if chain.row_digest(previous, _content(row)) != row.row_hash:
            return f"re-analysis {row.id}: its content was edited after it was stored"
        previous = row.row_hash
    return None
