"""The records store: register bundles, issue certificate numbers, query a unit's history.

One code path for SQLite and PostgreSQL (SQLAlchemy Core). Records are append-only: a new
registration of the same bundle supersedes the previous record instead of changing it. The
store keeps hashes and fingerprints only, never a private key.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable, Sequence
from datetime import UTC, datetime
from typing import Any

from sqlalchemy import Select, select
from sqlalchemy.dialects import postgresql, sqlite
from sqlalchemy.engine import URL, Connection, Engine, Row
from sqlalchemy.orm import aliased

from aatest.records import audit, chain, numbering, schema
from aatest.records.engine import open_engine
from aatest.records.errors import RecordsError
from aatest.records.models import CalibrationRecord, QuantityRecord, RecordFilter, Registration
from aatest.records.tables import calibrations, certificates, quantities, signed_files, units
from aatest.records.url import is_default_missing, redacted, resolve_url
from aatest.results import RunResults

#: the largest record id (a 64-bit signed integer in both databases)
_MAX_ID = 2**63 - 1


def as_utc(moment: datetime) -> datetime:
    """An aware UTC datetime (SQLite hands back naive ones; they were stored as UTC)."""
    return moment.replace(tzinfo=UTC) if moment.tzinfo is None else moment.astimezone(
        UTC)


class RecordStore:
    """A migrated records database; open it with :meth:`open`."""

    def __init__(self, engine: Engine, url: URL) -> None:
        self.engine = engine
        self.url = url

    @classmethod
    def open(cls, records_url: str | None = None, create: bool = True) -> RecordStore:
        """Connect to ``records_url`` (else ``AATEST_RECORDS``, else the default file), migrate.

        With ``create=False`` a SQLite file that does not exist is an error instead of being
        created (readers must not leave empty databases behind).
        """
        url = resolve_url(records_url)
        if not create and is_default_missing(url):
            raise RecordsError(f"no records store at {redacted(url)}")
        engine = open_engine(url)
        if schema.current_revision(engine) != schema.head_revision():
            schema.upgrade(engine)
        return cls(engine, url)

    def close(self) -> None:
        self.engine.dispose()

    def __enter__(self) -> RecordStore:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()

    @property
    def name(self) -> str:
        """The store's URL without password, for messages."""
        return redacted(self.url)

    def issue_certificate(self, prefix: str, issued_utc: datetime | None = None) -> str:
        """Allocate the next certificate number of ``prefix`` (see :mod:`.numbering`)."""
        when = as_utc(issued_utc or datetime.now(UTC))
        with self.engine.begin() as connection:
            return numbering.allocate(connection, prefix, when)

    def register(self, registration: Registration) -> int:
        """Append a record (superseding the previous record of the same bundle); its id.

        Idempotent: when the newest record of the bundle already holds this certificate
        number and these file hashes, its id is returned and nothing is written.
        """
        with self.engine.begin() as connection:
            return append_record(connection, registration)

    def begin_issue(self, prefix: str, issued_utc: datetime | None = None) -> Issue:
        """Open the transaction that issues a number and registers its bundle (:class:`Issue`)."""
        return Issue(self, prefix, as_utc(issued_utc or datetime.now(UTC)))

    def query(self, where: RecordFilter) -> list[CalibrationRecord]:
        """Records matching ``where``, oldest calibration first."""
        with self.engine.connect() as connection:
            rows = connection.execute(_filtered(where)).all()
            return _records(connection, rows)

    def recent(self, limit: int) -> list[CalibrationRecord]:
        """The ``limit`` newest current runs (not superseded, no diagnoses), newest first, each
        with its ``kind`` (a simulation is listed as such, never as a unit's calibration).

        What a station's list of recent runs shows; a lab's store grows without bound, so the
        limit is applied in the database rather than after loading every record.
        """
        query = (_filtered(RecordFilter(include_simulations=True))
                 .where(calibrations.c.command != "diagnose")
                 .order_by(None)
                 .order_by(calibrations.c.calibrated_utc.desc(), calibrations.c.id.desc())
                 .limit(limit))
        with self.engine.connect() as connection:
            return _records(connection, connection.execute(query).all())

    def history(self, serial: str, include_simulations: bool = False) -> list[CalibrationRecord]:
        """The current (not superseded) calibrations of a unit, oldest first (no diagnoses;
        simulations only when ``include_simulations``)."""
        where = RecordFilter(serial=serial, include_simulations=include_simulations)
        return [r for r in self.query(where) if r.command != "diagnose"]

    def get(self, key: str) -> CalibrationRecord:
        """The newest record with certificate number ``key`` (or record id ``key``)."""
        by_id = key.isascii() and key.isdigit()
        if by_id and int(key) > _MAX_ID:  # no such id; the database's integer cannot hold it
            raise RecordsError(f"no record {key!r} in {self.name}")
        column = calibrations.c.id if by_id else calibrations.c.certificate_number
        with self.engine.connect() as connection:
            rows = connection.execute(
                _base().where(column == (int(key) if by_id else key))
                .order_by(calibrations.c.id.desc()).limit(1)).all()
            found = _records(connection, rows)
        if not found:
            raise RecordsError(f"no record {key!r} in {self.name}")
        return found[0]

    def query_certificate(self, number: str) -> list[CalibrationRecord]:
        """Every record (also superseded ones) under certificate ``number``, oldest first."""
        with self.engine.connect() as connection:
            rows = connection.execute(_base().where(
                calibrations.c.certificate_number == number).order_by(calibrations.c.id)).all()
            return _records(connection, rows)

    def certificate_issued(self, number: str) -> bool:
        """Whether this store ever issued certificate ``number``."""
        with self.engine.connect() as connection:
            return connection.execute(select(certificates.c.number).where(
                certificates.c.number == number)).first() is not None

    def check_chain(self) -> chain.ChainReport:
        """Recompute the whole records chain (``aatest records check``)."""
        with self.engine.connect() as connection:
            return chain.check(connection)

    def chain_problems(self, record_id: int) -> list[str]:
        """Breaks of the chain links that vouch for record ``record_id`` (``aatest verify``)."""
        with self.engine.connect() as connection:
            return chain.record_problems(connection, record_id)

    def results_of(self, record_id: int) -> RunResults:
        """The stored results of a record (without figures), as the typed record."""
        with self.engine.connect() as connection:
            stored = connection.execute(select(calibrations.c.results).where(
                calibrations.c.id == record_id)).scalar_one()
        return RunResults.model_validate(stored)

    def latest_for_bundle(self, bundle: str) -> CalibrationRecord | None:
        """The newest record registered for the bundle whose main file is ``bundle``."""
        with self.engine.connect() as connection:
            rows = connection.execute(_base().where(calibrations.c.bundle == bundle)
                                      .order_by(calibrations.c.id.desc()).limit(1)).all()
            found = _records(connection, rows)
        return found[0] if found else None


def append_record(connection: Connection, registration: Registration) -> int:
    """Insert ``registration`` in the caller's transaction (see :meth:`RecordStore.register`)."""
    chain.lock(connection)  # ids and links in one order, whoever registers at once
    latest = connection.execute(
        select(calibrations.c.id, calibrations.c.certificate_number, calibrations.c.command,
               calibrations.c.results)
        .where(calibrations.c.bundle == registration.bundle)
        .order_by(calibrations.c.id.desc()).limit(1)).first()
    if latest is not None and _same(connection, latest, registration):
        return int(latest.id)  # registered already (a re-run after a crash): nothing new
    unit_id = _unit_id(connection, registration.model, registration.serial)
    fields = registration.model_dump(exclude={"model", "serial", "files", "quantities"})
    record_id = connection.execute(calibrations.insert().values(
        **fields, unit_id=unit_id, supersedes_id=None if latest is None else latest.id,
        registered_utc=datetime.now(UTC),
    ).returning(calibrations.c.id)).scalar_one()
    _insert_children(connection, record_id, registration)
    chain.append(connection, int(record_id))
    audit.append(connection, "register", registration.certificate_number or f"record {record_id}",
                 f"{registration.command} ({registration.kind})",
                 {"record_id": int(record_id), "bundle": registration.bundle,
                  "supersedes_id": None if latest is None else int(latest.id)})
    return int(record_id)


def _same(connection: Connection, latest: Any, registration: Registration) -> bool:
    """Whether record ``latest`` is ``registration`` already: same number, command, results
    and bundle file hashes (what a repeated registration of an unchanged bundle brings)."""
    return bool(latest.certificate_number == registration.certificate_number
                and latest.command == registration.command
                and latest.results == registration.results
                and _files_of(connection, int(latest.id)) == registration.files)


def _files_of(connection: Connection, record_id: int) -> dict[str, str]:
    rows = connection.execute(select(signed_files.c.name, signed_files.c.sha256).where(
        signed_files.c.calibration_id == record_id))
    return {row.name: row.sha256 for row in rows}


class Issue:
    """A certificate number held in an open transaction until its bundle is registered.

    The number is allocated (the counter row locked, :mod:`.numbering`) when the transaction
    opens, before the results are written, so the report, PDF and signature carry it; the
    record of the complete, signed bundle is inserted and everything committed together in
    :meth:`register`. A failure at any stage in between — or the process killed — rolls it
    all back: the register shows neither the number nor a record, and the next bundle gets
    the same number (no gap). Other stations wait on the counter meanwhile (SQLite: on the
    database write lock, up to the busy timeout).
    """

    def __init__(self, store: RecordStore, prefix: str, issued_utc: datetime) -> None:
        self._connection: Connection | None = store.engine.connect()
        self._transaction = self._connection.begin()
        try:
            self.number = numbering.allocate(self._connection, prefix, issued_utc)
        except BaseException:
            self.abandon()
            raise

    def register(self, registration: Registration) -> int:
        """Insert the bundle's record and commit it with the number; the record id."""
        if self._connection is None:
            raise RecordsError(f"certificate {self.number}: its transaction is already closed")
        try:
            record_id = append_record(self._connection, registration)
            self._transaction.commit()
        except BaseException:
            self.abandon()
            raise
        self._close()
        return record_id

    def abandon(self) -> None:
        """Roll the number back (the bundle was never completed); safe to call twice."""
        if self._connection is not None:
            if self._transaction.is_active:
                self._transaction.rollback()
            self._close()

    def _close(self) -> None:
        if self._connection is not None:
            self._connection.close()
            self._connection = None


def _unit_id(connection: Connection, model: str, serial: str) -> int:
    dialect = postgresql if connection.dialect.name == "postgresql" else sqlite
    connection.execute(dialect.insert(units).values(model=model, serial=serial)
                       .on_conflict_do_nothing(index_elements=["model", "serial"]))
    return int(connection.execute(select(units.c.id).where(
        (units.c.model == model) & (units.c.serial == serial))).scalar_one())


def _insert_children(connection: Connection, record_id: int, registration: Registration) -> None:
    if registration.files:
        connection.execute(signed_files.insert(), [
            {"calibration_id": record_id, "name": name, "sha256": digest}
            for name, digest in registration.files.items()])
    if registration.quantities:
        connection.execute(quantities.insert(), [
            {"calibration_id": record_id, "name": name, **q.model_dump()}
            for name, q in registration.quantities.items()])


def _base() -> Select[Any]:
    newer = aliased(calibrations, name="newer")
    superseded_by = (select(newer.c.id).where(newer.c.supersedes_id == calibrations.c.id)
                     .limit(1).scalar_subquery())
    return (select(calibrations, units.c.model, units.c.serial,
                   superseded_by.label("superseded_by"))
            .join(units, units.c.id == calibrations.c.unit_id))


def _filtered(where: RecordFilter) -> Select[Any]:
    query = _base()
    for column, value in ((units.c.serial, where.serial), (units.c.model, where.model),
                          (calibrations.c.procedure, where.procedure),
                          (calibrations.c.overall_verdict, where.verdict)):
        if value is not None:
            query = query.where(column == value)
    if not where.include_simulations:
        query = query.where(calibrations.c.kind != "simulation")
    if where.since_utc is not None:
        query = query.where(calibrations.c.calibrated_utc >= as_utc(where.since_utc))
    if where.until_utc is not None:
        query = query.where(calibrations.c.calibrated_utc <= as_utc(where.until_utc))
    if not where.include_superseded:
        newer = aliased(calibrations, name="newest")
        query = query.where(~select(newer.c.id).where(
            newer.c.supersedes_id == calibrations.c.id).exists())
    return query.order_by(calibrations.c.calibrated_utc, calibrations.c.id)


def _children(connection: Connection, ids: Iterable[int]) -> tuple[dict[int, Any], dict[int, Any]]:
    ids = list(ids)
    files: dict[int, dict[str, str]] = defaultdict(dict)
    values: dict[int, dict[str, QuantityRecord]] = defaultdict(dict)
    for row in connection.execute(select(signed_files).where(
            signed_files.c.calibration_id.in_(ids))):
        files[row.calibration_id][row.name] = row.sha256
    for row in connection.execute(select(quantities).where(quantities.c.calibration_id.in_(ids))):
        values[row.calibration_id][row.name] = QuantityRecord(
            value=row.value, expanded_uncertainty=row.expanded_uncertainty, unit=row.unit)
    return files, values


def _records(connection: Connection, rows: Sequence[Row[Any]]) -> list[CalibrationRecord]:
    files, values = _children(connection, (row.id for row in rows))
    out = []
    for row in rows:
        data = row._asdict()
        for drop in ("unit_id", "results", "previous_hash", "row_hash"):
            data.pop(drop, None)
        data.update(calibrated_utc=as_utc(row.calibrated_utc),
                    registered_utc=as_utc(row.registered_utc),
                    files=files.get(row.id, {}), quantities=values.get(row.id, {}))
        out.append(CalibrationRecord(**data))
    return out
