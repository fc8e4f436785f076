"""The audit trail of the records store, and certificates superseded or withdrawn.

Nothing in the store is edited: every change — a record registered, a certificate superseded
or withdrawn, a reference standard added or retired — appends one ``audit_log`` row (who, when,
what, why) in the same transaction as the change. The rows are chained like the records
(:func:`aatest.records.chain.row_digest` over the previous row's hash and the row's canonical
JSON), so ``aatest records audit`` shows an edited, re-hashed or removed row.

A certificate is never changed either: ``aatest records supersede NUMBER --reason …`` marks it
superseded by a newer certificate (``--by NEW``, e.g. the number ``aatest analyze`` issued for
the corrected bundle) or withdrawn, in ``certificate_status``; ``verify`` reports it as such.
"""

from __future__ import annotations

import getpass
import os
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any, Protocol

from sqlalchemy import select
from sqlalchemy.engine import Connection, Engine

from aatest.records import chain
from aatest.records.errors import RecordsError
from aatest.records.tables import audit_log, certificate_status, certificates

AUDIT_FORMAT = "aatest-audit/1"
_CONTENT = ("id", "at_utc", "who", "action", "subject", "reason", "detail")


class Store(Protocol):
    """What the audit reads of a records store (:class:`~aatest.records.store.RecordStore`).

    The store appends audit rows in its own transactions, so it imports this module; the
    audit names only the two attributes it needs instead of importing the store back.
    """

    @property
    def engine(self) -> Engine:
        """The store's SQLAlchemy engine."""
        ...

    @property
    def name(self) -> str:
        """The store as a person reads it (its URL without a password)."""
        ...


def actor() -> str:
    """Who makes the change: ``AATEST_OPERATOR``, else the login name."""
    try:
        return os.environ.get("AATEST_OPERATOR") or getpass.getuser()
    except (KeyError, OSError):
        return "unknown"


def _content(row: Any) -> dict[str, Any]:
    content = {name: getattr(row, name) for name in _CONTENT}
    content["at_utc"] = chain._utc_text(row.at_utc)
    return {"audit": AUDIT_FORMAT, **content}


def append(connection: Connection, action: str, subject: str, reason: str = "",
           detail: dict[str, Any] | None = None) -> None:
    """Append one audit row inside the caller's transaction (which holds the chain lock)."""
    chain.lock(connection)
    last = connection.execute(select(audit_log.c.row_hash).order_by(
        audit_log.c.id.desc()).limit(1)).scalar()
    previous = str(last) if last else chain.GENESIS
    record_id = connection.execute(audit_log.insert().values(
        at_utc=datetime.now(UTC), who=actor(), action=action, subject=subject, reason=reason,
        detail=detail or {}, previous_hash=previous, row_hash="").returning(
        audit_log.c.id)).scalar_one()
    row = connection.execute(select(audit_log).where(audit_log.c.id == record_id)).one()
    connection.execute(audit_log.update().where(audit_log.c.id == record_id).values(
        row_hash=chain.row_digest(previous, _content(row))))


@dataclass(frozen=True)
class AuditReport:
    """The audit rows as printed, and the first row whose hash or link fails (if any)."""

    lines: list[str]
    broken: str | None


def report(store: Store) -> AuditReport:
    """Every audit row, oldest first, with the chain checked (``aatest records audit``)."""
    lines, previous = [], chain.GENESIS
    with store.engine.connect() as connection:
        rows = connection.execute(select(audit_log).order_by(audit_log.c.id)).all()
    for row in rows:
        lines.append(f"{chain._utc_text(row.at_utc)[:19]}Z  {row.who:16s} {row.action:18s} "
                     f"{row.subject:18s} {row.reason}")
        if row.previous_hash != previous:
            return AuditReport(lines, f"audit row {row.id}: its link to the row before it is "
                               "broken (that row was re-hashed or removed)")
        if chain.row_digest(previous, _content(row)) != row.row_hash:
            return AuditReport(lines, f"audit row {row.id}: its content was edited")
        previous = row.row_hash
    return AuditReport(lines, None)


def supersede(store: Store, number: str, reason: str, by: str | None) -> str:
    """Mark certificate ``number`` superseded by ``by`` (or withdrawn without); what happened."""
    if not reason.strip():
        raise RecordsError("a reason is required (--reason)")
    with store.engine.begin() as connection:
        for known in (number, by):
            if known and connection.execute(select(certificates.c.number).where(
                    certificates.c.number == known)).first() is None:
                raise RecordsError(f"certificate {known!r} was never issued by {store.name}")
        if by == number:
            raise RecordsError(f"certificate {number} cannot supersede itself")
        if status_of(connection, number) is not None:
            raise RecordsError(f"certificate {number} is already {status_of(connection, number)}")
        status = "superseded" if by else "withdrawn"
        connection.execute(certificate_status.insert().values(
            number=number, status=status, replaced_by=by, reason=reason, who=actor(),
            at_utc=datetime.now(UTC)))
        append(connection, status, number, reason, {"replaced_by": by} if by else {})
    return f"certificate {number} {status}" + (f" by {by}" if by else "") + f": {reason}"


def status_of(connection: Connection, number: str) -> str | None:
    """``superseded by X on DATE: reason`` / ``withdrawn …`` for ``number``; None when valid."""
    row = connection.execute(select(certificate_status).where(
        certificate_status.c.number == number)).first()
    if row is None:
        return None
    by = f" by {row.replaced_by}" if row.replaced_by else ""
    return f"{row.status}{by} on {chain._utc_text(row.at_utc)[:10]}: {row.reason}"


def supersedes(connection: Connection, number: str) -> list[str]:
    """The certificates ``number`` replaced (the link back)."""
    return list(connection.execute(select(certificate_status.c.number).where(
        certificate_status.c.replaced_by == number)).scalars())
