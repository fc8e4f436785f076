"""Reverse traceability: which certificates used a reference, and what a correction changes.

ISO/IEC 17025 §7.10 (nonconforming work): a reference standard found out of tolerance makes
every result it contributed to suspect. :func:`affected` names those certificates (every
current record whose results list the reference); :func:`assess` re-analyses their recordings
in a batch with the reference corrected and compares, per certificate and judged quantity, the
issued value ± U and verdict with the corrected ones. The issued certificates are not changed:
the corrected results are stored as re-analyses, and a certificate whose verdict changes is for
the lab to supersede or withdraw (``aatest records supersede``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

from aatest.batch import ledger
from aatest.batch.correction import ReferenceCorrection
from aatest.batch.method import method_hash, method_of
from aatest.batch.runner import BatchReport, Progress, run_batch
from aatest.batch.selection import Selected, from_store
from aatest.records import references
from aatest.records.errors import RecordsError
from aatest.records.models import RecordFilter
from aatest.records.store import RecordStore


@dataclass(frozen=True)
class Judged:
    """One judged quantity of a certificate, as issued and as corrected."""

    quantity: str
    channel: str
    unit: str
    old_value: float
    old_u: float | None
    old_verdict: str
    new_value: float | None = None
    new_u: float | None = None
    new_verdict: str | None = None

    @property
    def changes(self) -> bool:
        """Whether the corrected verdict differs from the issued one."""
        return self.new_verdict is not None and self.new_verdict != self.old_verdict


@dataclass
class Certificate:
    """One affected certificate: its record, and (with a correction) its re-evaluation."""

    selected: Selected
    judged: list[Judged] = field(default_factory=list)
    new_overall: str | None = None
    error: str | None = None

    @property
    def number(self) -> str:
        record = self.selected.record
        assert record is not None
        return record.certificate_number or f"record {record.id}"

    @property
    def changes(self) -> bool:
        """Whether the overall verdict or any judged quantity's verdict changes."""
        record = self.selected.record
        assert record is not None
        return (self.new_overall is not None and self.new_overall != record.overall_verdict) \
            or any(j.changes for j in self.judged)


@dataclass
class Impact:
    """The answer of ``records impact``."""

    reference: str
    certificates: list[Certificate]
    correction: ReferenceCorrection | None = None
    batch: BatchReport | None = None


def _check_reference(store: RecordStore, reference: str,
                     correction: ReferenceCorrection | None) -> None:
    known = {r.identifier: r for r in references.listing(store, include_retired=True)}
    if reference not in known:
        raise RecordsError(f"reference {reference!r} is not registered in {store.name}")
    if correction is None:
        return
    if correction.reference != reference:
        raise RecordsError(f"the correction is for reference {correction.reference!r}, "
                           f"not {reference!r}")
    problem = correction.fits_kind(known[reference].kind)
    if problem:
        raise RecordsError(f"correction of {reference}: {problem}")


def affected(store: RecordStore, reference: str, since: datetime | None = None,
             include_simulations: bool = False) -> list[Selected]:
    """Every current certificate record that used ``reference`` (since ``since``)."""
    _check_reference(store, reference, None)
    where = RecordFilter(since_utc=since, include_simulations=include_simulations)
    return [s for s in from_store(store, where, reference)
            if s.record is not None and s.record.certificate_number]


def _judged(old_rows: Sequence[dict[str, Any]], new_rows: Sequence[dict[str, Any]] | None
            ) -> list[Judged]:
    new_by_key = {(r["quantity"], r["channel"]): r for r in new_rows or []}
    out = []
    for old in old_rows:
        new = new_by_key.get((old["quantity"], old["channel"]), {})
        out.append(Judged(old["quantity"], old["channel"], old.get("unit", ""),
                          float(old["value"]), old.get("expanded_uncertainty"), old["verdict"],
                          new.get("value"), new.get("expanded_uncertainty"), new.get("verdict")))
    return out


def assess(  # noqa: PLR0913 - the selection, then the batch's own options by keyword
        store: RecordStore, reference: str, correction: ReferenceCorrection | None,
           since: datetime | None = None, include_simulations: bool = False, *,
           scheduler: str | None = None, workers: int = 2, processes: bool = True,
           progress: Progress | None = None) -> Impact:
    """The certificates that used ``reference``; with a correction, re-analysed and compared."""
    _check_reference(store, reference, correction)
    chosen = affected(store, reference, since, include_simulations)
    certificates = [Certificate(s) for s in chosen]
    if correction is None or not chosen:
        return Impact(reference, certificates, correction)
    batch = run_batch(store, chosen, "analyze", correction, scheduler=scheduler,
                      workers=workers, processes=processes, progress=progress)
    mhash = method_hash(method_of("analyze", correction))
    results = {r.subject: r for r in ledger.stored(store, mhash)}
    failures = {f.subject: f.error for f in batch.failures}
    for cert in certificates:
        record = cert.selected.record
        assert record is not None
        redone = results.get(cert.selected.subject)
        cert.error = failures.get(cert.selected.subject)
        cert.new_overall = redone.overall_verdict if redone else None
        cert.judged = _judged(record.verdicts, redone.verdicts if redone else None)
    return Impact(reference, certificates, correction, batch)


def _measured(value: float | None, u: float | None, unit: str) -> str:
    if value is None:
        return "—"
    return f"{value:.4g}" + (f" ± {u:.2g}" if u is not None else "") + f" {unit}".rstrip()


def impact_text(impact: Impact) -> str:
    """The report a quality manager reads: per certificate, issued → corrected."""
    lines = [f"reference {impact.reference}: {len(impact.certificates)} certificate(s) used it"]
    if impact.correction is not None:
        lines.append(f"correction found {impact.correction.found_on}: {impact.correction.reason}")
    for cert in impact.certificates:
        record = cert.selected.record
        assert record is not None
        head = (f"{cert.number}  {record.model} {record.serial}  "
                f"{record.calibrated_utc.date()}  {record.overall_verdict}")
        if impact.correction is None:
            lines.append(head)
            continue
        if cert.error is not None:
            lines.append(f"{head} → not re-analysed: {cert.error}")
            continue
        flag = "VERDICT CHANGES" if cert.changes else "verdict unchanged"
        lines.append(f"{head} → {cert.new_overall}  {flag}")
        for j in cert.judged:
            mark = "  ← changes" if j.changes else ""
            lines.append(f"    {j.quantity} {j.channel}: {_measured(j.old_value, j.old_u, j.unit)}"
                         f" {j.old_verdict} → {_measured(j.new_value, j.new_u, j.unit)} "
                         f"{j.new_verdict or '—'}{mark}")
    if impact.correction is not None:
        changed = sum(cert.changes for cert in impact.certificates)
        lines.append(f"{changed} of {len(impact.certificates)} certificate(s) change verdict")
    return "\n".join(lines)


def impact_json(impact: Impact) -> dict[str, Any]:
    """``records impact --json``: the same content, machine-readable."""
    certs = []
    for cert in impact.certificates:
        record = cert.selected.record
        assert record is not None
        certs.append({
            "certificate_number": record.certificate_number, "record_id": record.id,
            "serial": record.serial, "model": record.model,
            "calibrated_utc": record.calibrated_utc.isoformat(timespec="seconds"),
            "recording": cert.selected.recording, "overall_verdict": record.overall_verdict,
            "corrected_overall_verdict": cert.new_overall, "verdict_changes": cert.changes
            if impact.correction is not None else None, "error": cert.error,
            "judged": [{**j.__dict__, "changes": j.changes} for j in cert.judged]})
    return {"reference": impact.reference, "certificates": certs,
            "correction": None if impact.correction is None
            else impact.correction.model_dump(mode="json")}
