"""The register of reference standards, and the check that refuses a calibration with an
overdue one before anything moves.

A rig file names the references it uses (``references: [ENC-1, LOG-7]``); each is registered
in the records store with ``aatest references add`` — its certificate, issuing lab, calibration
and due date and stated accuracy. Before a run starts, every named reference must be known and
not retired, and one past its due date refuses the run (exit 2) unless the operator overrides
with ``--allow-overdue "reason"``, which the certificate prints as a non-conformity. The
references used are written into the results metadata, so each calibration record keeps them
(reverse traceability: which calibrations relied on a reference later found out of tolerance).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from datetime import UTC, date, datetime
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator
from sqlalchemy import select

from aatest.engine.errors import InputError
from aatest.records import audit
from aatest.records.errors import RecordsError
from aatest.records.store import RecordStore
from aatest.records.tables import reference_standards

#: results-metadata keys the certificate reads
REFERENCES_KEY = "reference_standards"
NONCONFORMITIES_KEY = "nonconformities"

ReferenceKind = Literal["encoder", "rate-reference", "data-logger", "thermometer", "chamber"]


class ReferenceStandard(BaseModel):
    """One reference instrument and its calibration (``aatest references add``)."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    identifier: str = Field(min_length=1, max_length=64)
    kind: ReferenceKind
    certificate_number: str = Field(min_length=1, max_length=64)
    issuing_lab: str = Field(min_length=1, max_length=128)
    calibrated_on: date
    due_on: date
    accuracy: str = Field(min_length=1, description="stated accuracy, e.g. '±1 arcsec'")
    retired_utc: datetime | None = None
    retired_reason: str | None = None

    @model_validator(mode="after")
    def _due_after_calibration(self) -> ReferenceStandard:
        if self.due_on <= self.calibrated_on:
            raise ValueError(f"reference {self.identifier}: due date {self.due_on} is not after "
                             f"its calibration on {self.calibrated_on}")
        return self

    def overdue(self, today: date) -> bool:
        """Past its due date on ``today`` (the due date itself is still valid)."""
        return today > self.due_on

    def certificate_row(self) -> dict[str, Any]:
        """What the certificate's reference table prints (JSON, kept in the results)."""
        return self.model_dump(mode="json", exclude={"retired_utc", "retired_reason"})


def add(store: RecordStore, reference: ReferenceStandard) -> None:
    """Register ``reference``; an identifier already registered is an error."""
    with store.engine.begin() as connection:
        if connection.execute(select(reference_standards.c.id).where(
                reference_standards.c.identifier == reference.identifier)).first():
            raise RecordsError(f"reference {reference.identifier!r} is already registered "
                               f"in {store.name} (retire it and register a new identifier)")
        connection.execute(reference_standards.insert().values(
            **reference.model_dump(exclude={"retired_utc", "retired_reason"}),
            added_utc=datetime.now(UTC)))
        audit.append(connection, "reference-add", reference.identifier, "",
                     reference.certificate_row())


def listing(store: RecordStore, include_retired: bool = False) -> list[ReferenceStandard]:
    """Registered references by identifier (retired ones only when asked)."""
    query = select(reference_standards).order_by(reference_standards.c.identifier)
    if not include_retired:
        query = query.where(reference_standards.c.retired_utc.is_(None))
    with store.engine.connect() as connection:
        rows = connection.execute(query).all()
    return [ReferenceStandard(**{k: v for k, v in row._asdict().items()
                                 if k not in ("id", "added_utc")}) for row in rows]


def retire(store: RecordStore, identifier: str, reason: str) -> None:
    """Mark a reference as no longer in use (it stays in the register for traceability)."""
    with store.engine.begin() as connection:
        done = connection.execute(reference_standards.update().where(
            (reference_standards.c.identifier == identifier)
            & reference_standards.c.retired_utc.is_(None)).values(
            retired_utc=datetime.now(UTC), retired_reason=reason))
        if done.rowcount != 1:
            raise RecordsError(f"no reference {identifier!r} in use in {store.name}")
        audit.append(connection, "reference-retire", identifier, reason)


@dataclass
class Preflight:
    """The references a run uses, checked; the non-conformities the operator accepted."""

    references: list[ReferenceStandard] = field(default_factory=list)
    nonconformities: list[str] = field(default_factory=list)

    def metadata(self) -> dict[str, Any]:
        """Keys written into the results metadata (and so into the calibration record)."""
        return {REFERENCES_KEY: [r.certificate_row() for r in self.references],
                NONCONFORMITIES_KEY: list(self.nonconformities)}


def check(store: RecordStore, identifiers: Sequence[str], today: date,
          allow_overdue: str | None) -> Preflight:
    """Check the rig's references before the run (InputError, exit 2, on any problem).

    Unknown and retired references are always refused; overdue ones unless ``allow_overdue``
    gives the reason, which becomes a non-conformity on the certificate.
    """
    known = {r.identifier: r for r in listing(store, include_retired=True)}
    preflight, problems = Preflight(), []
    for identifier in identifiers:
        ref = known.get(identifier)
        if ref is None:
            problems.append(f"reference {identifier!r} is not registered in {store.name} "
                            "(aatest references add)")
        elif ref.retired_utc is not None:
            problems.append(f"reference {identifier!r} was retired ({ref.retired_reason})")
        else:
            preflight.references.append(ref)
            if ref.overdue(today):
                problems.append(f"reference {identifier!r} ({ref.kind}, certificate "
                                f"{ref.certificate_number}) was due on {ref.due_on}")
    overdue = [p for p in problems if " was due on " in p]
    if allow_overdue and overdue and len(overdue) == len(problems):
        preflight.nonconformities += [f"{p}; used with the operator's override: {allow_overdue}"
                                      for p in overdue]
        return preflight
    if problems:
        hint = " (--allow-overdue \"reason\" proceeds and prints it as a non-conformity)" \
            if overdue and len(overdue) == len(problems) else ""
        raise InputError("; ".join(problems) + hint + " — nothing was moved")
    return preflight
