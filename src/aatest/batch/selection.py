"""Which recordings a batch runs over: records from the store, or every recording under a URL.

From the store, the current (not superseded) records of runs and analyses that match the
options — unit serial, procedure, calibrated since, reference standard used — each with the
``recording.mcap`` beside its bundle. Under a prefix (a local directory or any fsspec URL),
every ``recording.mcap`` found; one whose bundle is registered is linked to its record.

Each selected recording is a :class:`~aatest.batch.task.Task` subject: ``record:ID`` when it
has a record (the re-analysis is linked to it), else the recording's location itself.
"""

from __future__ import annotations

import posixpath
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from sqlalchemy import Text, cast, select

from aatest.engine.errors import InputError
from aatest.recording.writer import RECORDING_NAME
from aatest.records.models import CalibrationRecord, RecordFilter
from aatest.records.references import REFERENCES_KEY
from aatest.records.store import RecordStore
from aatest.records.tables import calibrations

#: record commands whose bundle sits beside a recording (``report`` re-signs a run's bundle)
RECORDED_COMMANDS = frozenset({"run", "analyze", "report"})
#: the report a run writes beside its recording (how a recording finds its record)
REPORT_NAME = "report.html"


@dataclass(frozen=True)
class Selected:
    """One recording to process, and the record it re-analyses (if any)."""

    subject: str
    recording: str
    record: CalibrationRecord | None = None


def recording_beside(bundle: str) -> str:
    """The ``recording.mcap`` in the directory of ``bundle`` (a path or URL)."""
    return posixpath.join(posixpath.dirname(bundle), RECORDING_NAME)


def references_of(results: dict[str, Any]) -> set[str]:
    """Identifiers of the reference standards a stored result says it used."""
    rows = (results.get("metadata") or {}).get(REFERENCES_KEY) or []
    return {str(row.get("identifier")) for row in rows if isinstance(row, dict)}


def using_reference(store: RecordStore, ids: Sequence[int], reference: str) -> set[int]:
    """Which of the records ``ids`` used reference standard ``reference``.

    The database narrows the candidates by the identifier appearing in the stored results
    (text match, the same on SQLite and PostgreSQL); each candidate's reference list is then
    read to confirm it (an identifier that is a substring of another is not a match).
    """
    found: set[int] = set()
    needle = f'%"{reference}"%'
    with store.engine.connect() as connection:
        for start in range(0, len(ids), 500):
            rows = connection.execute(select(calibrations.c.id, calibrations.c.results).where(
                calibrations.c.id.in_(list(ids[start:start + 500]))
                & cast(calibrations.c.results, Text).like(needle)))
            found.update(int(row.id) for row in rows if reference in references_of(row.results))
    return found


def from_store(store: RecordStore, where: RecordFilter,
               reference: str | None = None) -> list[Selected]:
    """The current records matching ``where`` (and using ``reference``), oldest first."""
    records = [r for r in store.query(where) if r.command in RECORDED_COMMANDS]
    if reference is not None:
        users = using_reference(store, [r.id for r in records], reference)
        records = [r for r in records if r.id in users]
    return [Selected(f"record:{r.id}", recording_beside(r.bundle), r) for r in records]


def from_prefix(prefix: str, store: RecordStore | None) -> list[Selected]:
    """Every ``recording.mcap`` under ``prefix`` (a directory or fsspec URL), sorted.

    A URL is opened with aatest's storage options (:mod:`aatest.storage`: the
    ``AATEST_S3_ENDPOINT`` and credentials the rest of aatest uses), so a prefix on a lab's
    S3-compatible server lists the same objects ``aatest analyze`` would read.

    Raises
    ------
    InputError
        Nothing can be listed there, or no recording is found.
    """
    from aatest.storage import locate
    from aatest.storage.location import RemotePath, StorageError

    where = locate(prefix)
    try:
        if isinstance(where, RemotePath):
            found = [str(where / name) for name in where.members()
                     if posixpath.basename(name) == RECORDING_NAME]
        else:
            found = [str(p) for p in sorted(where.resolve().rglob(RECORDING_NAME)) if p.is_file()]
    except (OSError, StorageError) as exc:
        raise InputError(f"{prefix}: cannot list recordings there: {exc}") from exc
    if not found:
        raise InputError(f"{prefix}: no {RECORDING_NAME} found under it")
    out = []
    for location in found:
        record = None
        if store is not None:
            report = posixpath.join(posixpath.dirname(location), REPORT_NAME)
            record = store.latest_for_bundle(report)
        subject = f"record:{record.id}" if record is not None else location
        out.append(Selected(subject, location, record))
    return out
