"""``aatest verify`` against the records: is the bundle still the one that was registered?

The signature proves the bundle is self-consistent; the record proves it is the bundle the lab
issued. Files changed or removed since registration, a different certificate number, or a
signature by another key than the registered fingerprint are each reported by name.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from aatest.bundle.manifest import UnsafeNameError, file_sha256, member_path
from aatest.bundle.signing import signature_path
from aatest.records.models import CalibrationRecord
from aatest.records.store import RecordStore
from aatest.storage import RemotePath


def _json_field(path: Path | RemotePath, key: str) -> Any:
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None  # missing or unreadable: the file comparison reports it
    return document.get(key) if isinstance(document, dict) else None


def find_record(report_path: Path, store: RecordStore) -> CalibrationRecord | None:
    """The newest record of this bundle: by location, else by the certificate number it states."""
    record = store.latest_for_bundle(str(report_path.resolve()))
    if record is not None:
        return record
    number = _json_field(report_path.with_name("results.json"), "certificate_number")
    if isinstance(number, str) and number:
        found = store.query_certificate(number)
        return found[-1] if found else None
    return None


def _file_reasons(report_path: Path | RemotePath, record: CalibrationRecord,
                  label: str) -> list[str]:
    reasons = []
    for name, digest in sorted(record.files.items()):
        try:
            member = member_path(report_path.parent, name)
        except UnsafeNameError as exc:
            reasons.append(f"record {label} is malformed: {exc}")
            continue
        if not member.is_file():
            reasons.append(f"{name} removed since it was registered ({label})")
        elif file_sha256(member) != digest:
            reasons.append(f"{name} changed since it was registered ({label})")
    return reasons


def record_reasons(report_path: Path | RemotePath, record: CalibrationRecord) -> list[str]:
    """Every difference between the bundle around ``report_path`` and its ``record``."""
    label = f"record {record.certificate_number or record.id} of {record.registered_utc:%Y-%m-%d}"
    reasons = _file_reasons(report_path, record, label)
    stated = _json_field(report_path.with_name("results.json"), "certificate_number")
    if report_path.with_name("results.json").is_file() and stated != record.certificate_number:
        reasons.append(f"certificate number {stated!r} in results.json, but the record issued "
                       f"{record.certificate_number!r}")
    signed_by = _json_field(signature_path(report_path), "fingerprint")
    if record.key_fingerprint and signed_by and signed_by != record.key_fingerprint:
        reasons.append(f"signed by key {signed_by}, the record registered key "
                       f"{record.key_fingerprint}")
    if record.key_fingerprint and not signature_path(report_path).is_file():
        reasons.append(f"signature {signature_path(report_path).name} removed ({label})")
    return reasons


def unregistered_reasons(report_path: Path, store: RecordStore) -> list[str]:
    """Why a bundle without a record in ``store`` is not one the store's lab issued.

    Called when :func:`find_record` found nothing: a certificate number the store never issued
    (or none at all) means the bundle was not registered here, however valid its signature.
    """
    number = _json_field(report_path.with_name("results.json"), "certificate_number")
    if not isinstance(number, str) or not number:
        return [f"results.json states no certificate number, and no record of this bundle is "
                f"in {store.name}"]
    if not store.certificate_issued(number):
        return [f"certificate number {number!r} was never issued by {store.name}"]
    return [f"certificate number {number!r} was issued by {store.name}, but no record of "
            "this bundle holds it"]
