"""Registration of what ``run``/``analyze``/``report`` produce, at the one point they share.

The CLI opens a :func:`registering` scope (records URL, lab profile, command), which installs
a :class:`Registrar` as the engine's bundle observer; the session calls its ``before_signing``
once results are complete — the next certificate number is allocated in a transaction that
stays open and is written into the results, so it is in ``results.json`` and on the
certificate before the signature covers them — and ``after_signing`` once the bundle is final
(report, PDF, signature), which appends the record with the SHA-256 of every bundle file and
commits it together with the number. A failure in between rolls both back (:class:`Issue`):
numbers exist only for complete, registered certificates. Outside a scope (library use, other
tests) both are no-ops, so nothing is registered behind a caller's back.

An unreachable database must not cost the measurement: the files are written without a
number, and the :class:`RecordsUnavailable` error is raised when the scope closes (exit 2).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from aatest.bundle import observers as bundle_observers
from aatest.engine.analysis.results_file import results_json
from aatest.engine.simulation import SIMULATION_PREFIX, is_simulation
from aatest.records import extract
from aatest.records.errors import RecordsUnavailable
from aatest.records.lab import LabProfile
from aatest.records.models import QuantityRecord, Registration
from aatest.records.store import Issue, RecordStore, as_utc
from aatest.results import RunResults
from aatest.results.root import RunMetadata
from aatest.storage import Where

CERTIFICATE_KEY = "certificate_number"
#: commands whose results earn a new certificate number (``report`` re-signs the same one)
ISSUING_COMMANDS = frozenset({"run", "analyze"})
@dataclass
class Registrar:
    """The records side of one CLI command."""

    records_url: str | None
    lab: LabProfile
    command: str
    error: RecordsUnavailable | None = None
    _store: RecordStore | None = field(default=None, repr=False)
    _issue: Issue | None = field(default=None, repr=False)
    #: results-metadata keys from the checks before the run (references used, non-conformities)
    preflight: dict[str, Any] = field(default_factory=dict)

    def store(self) -> RecordStore:
        if self._store is None:
            self._store = RecordStore.open(self.records_url)
        return self._store

    def close(self) -> None:
        """Roll back a number whose bundle was never registered; close the store."""
        self._abandon()
        if self._store is not None:
            self._store.close()

    def _abandon(self) -> None:
        issue, self._issue = self._issue, None
        if issue is not None:
            issue.abandon()

    def assign_certificate(self, results: RunResults) -> None:
        """Hold the next number for ``results`` (``run``/``analyze``) in the transaction that
        will register the bundle; ``report`` keeps a number that was issued (one that never
        was — its bundle was not registered — is replaced by the next)."""
        stated = results.certificate_number
        if self.command not in ISSUING_COMMANDS and stated and self._issued(stated):
            return
        self._abandon()  # a bundle begun in this scope and never registered
        results.certificate_number = None
        try:
            self._issue = self.store().begin_issue(certificate_prefix(results, self.lab))
        except RecordsUnavailable as exc:
            self.error = exc
            return
        results.certificate_number = self._issue.number

    def _issued(self, number: str) -> bool:
        try:
            return self.store().certificate_issued(number)
        except RecordsUnavailable as exc:
            self.error = exc
            return True  # keep it: the store cannot say otherwise

    def before_signing(self, results: RunResults) -> None:
        """Bundle observer: the certificate number and the issuing lab's identity, before the
        results are written (so the signature covers what the certificate prints)."""
        self.assign_certificate(results)
        results.metadata.lab = self.lab.certificate_identity()
        for key, value in self.preflight.items():
            setattr(results.metadata, key, value)

    def after_signing(self, results: RunResults, report: Where) -> None:
        """Bundle observer: register the finished bundle."""
        self.register(results, report)

    def register(self, results: RunResults, bundle: Where) -> int | None:
        """Append the record of ``bundle`` — committing its held number with it; ``None``
        when the store is unreachable."""
        issue, self._issue = self._issue, None
        if self.error is not None:
            return None
        try:
            registration = registration_for(results, bundle, self.command, self.lab)
            if issue is not None and issue.number == registration.certificate_number:
                return issue.register(registration)
            if issue is not None:  # the results lost the number held for them
                issue.abandon()
            return self.store().register(registration)
        except RecordsUnavailable as exc:
            self.error = exc
            return None
        finally:
            if issue is not None:
                issue.abandon()  # no-op after a commit


@contextmanager
def registering(records_url: str | None, lab: LabProfile, command: str) -> Iterator[Registrar]:
    """Register everything the enclosed session call produces; raise a deferred DB error."""
    registrar = Registrar(records_url, lab, command)
    try:
        with bundle_observers.observing(registrar):
            yield registrar
    finally:
        registrar.close()
    if registrar.error is not None:
        raise RecordsUnavailable(f"{registrar.error} — the files were written, but not registered")


def certificate_prefix(results: RunResults, lab: LabProfile) -> str:
    """The number series: ``SIM`` for a simulation (whatever the lab profile says), else the
    lab's prefix (which may not be ``SIM``)."""
    return SIMULATION_PREFIX if is_simulation(results) else lab.certificate_prefix


def bundle_files(bundle: Where) -> dict[str, str]:
    """SHA-256 of the bundle's files: what the signature covers (also for unsigned bundles)."""
    from aatest.bundle.signing import bundle_hashes

    return bundle_hashes(bundle)


def _calibrated_utc(results: RunResults) -> datetime:
    try:
        return as_utc(datetime.fromisoformat(str(results.metadata.started_utc)))
    except ValueError:
        return datetime.now(UTC)  # imported data without a start time: registered now


def registration_for(
    results: RunResults, bundle: Where, command: str, lab: LabProfile
) -> Registration:
    """The record of ``bundle`` (its main file, e.g. ``report.html``; a URL on object
    storage is recorded as it is) and its ``results``."""
    meta = results.metadata
    model, serial = extract.unit_of(results)
    stored = results_json(results)
    stored.pop("figures", None)  # figures are in the bundle
    return Registration(
        model=model, serial=serial, certificate_number=results.certificate_number,
        command=command, kind="simulation" if is_simulation(results) else "calibration",
        procedure=results.procedure or meta.procedure or "?",
        procedure_sha256=meta.procedure_sha256, rig=dict(results.rig),
        plugin_versions=dict(meta.plugin_versions),
        operator=meta.operator, lab=lab.name, calibrated_utc=_calibrated_utc(results),
        overall_verdict=results.overall, verdicts=extract.verdict_rows(results),
        results=stored, bundle=str(bundle.resolve()),
        key_fingerprint=results.signature.fingerprint if results.signature else None,
        files=bundle_files(bundle),
        quantities={q.name: QuantityRecord(value=q.value, unit=q.unit,
                                           expanded_uncertainty=q.expanded_uncertainty)
                    for q in extract.key_quantities(results, lab.frf_reference_frequency_hz)},
    )


def _results_for(data: Where) -> RunResults:
    """The run's results next to ``data``, else the recording's own metadata."""
    from aatest.engine.analysis.results_file import RESULTS_FILE, plain_metadata, read_results

    folder = data if data.is_dir() else data.parent
    if (folder / RESULTS_FILE).is_file():
        return read_results(folder)
    from aatest.recording import read_dataset

    dataset = read_dataset(data)
    return RunResults(procedure=dataset.procedure,
                      metadata=RunMetadata.model_validate(plain_metadata(dict(dataset.metadata))))


def register_diagnosis(registrar: Registrar, data: Where, json_out: Path | None) -> int | None:
    """Register what ``aatest diagnose`` wrote (its report, else its JSON) for the run's unit."""
    out_dir: Where = json_out.parent if json_out is not None else data
    report = out_dir / "diagnosis.html"
    bundle = report if report.is_file() else json_out
    if bundle is None or not bundle.is_file():
        return None
    results = _results_for(data)
    results.certificate_number = None  # a diagnosis is not a certificate
    return registrar.register(results, bundle)
