"""Check a signed bundle: intact files, a valid signature, and a key the verifier trusts.

Three independent questions, each answered with named reasons: is the signature file well
formed and does its signature hold over its manifest; do the files below the report match the
manifest (nothing changed, removed or added); and was it made by a key the lab trusts, within
the key's validity period (:mod:`.trust`) — the key a signature carries proves nothing alone.
"""

from __future__ import annotations

import base64
import binascii
import json
from collections.abc import Sequence
from datetime import UTC, datetime
from typing import Any

from cryptography.exceptions import InvalidSignature
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PublicKey

from aatest.bundle import manifest
from aatest.bundle.signature_format import (
    ALGORITHM,
    BUNDLE_FILES,
    FINGERPRINT_META,
    LEGACY_FORMAT,
    SIGNATURE_FORMAT,
    VerifyResult,
    key_fingerprint,
    signature_path,
    signed_payload,
)
from aatest.bundle.trust import TrustedKey, decide
from aatest.storage import Where, locate

_NEEDED = ("algorithm", "public_key", "files", "signature")


def _is_text_map(value: Any) -> bool:
    return isinstance(value, dict) and all(
        isinstance(k, str) and isinstance(v, str) for k, v in value.items())


def _shape_problem(document: Any, name: str) -> str | None:
    """What is wrong with the structure of a parsed signature document, if anything."""
    if not isinstance(document, dict) or any(k not in document for k in _NEEDED):
        return f"signature file {name} lacks one of {', '.join(_NEEDED)}"
    if document["algorithm"] != ALGORITHM:
        return f"signature algorithm {document['algorithm']!r} is not {ALGORITHM}"
    form = document.get("format", LEGACY_FORMAT)
    if form not in (SIGNATURE_FORMAT, LEGACY_FORMAT):
        return f"signature format {form!r} is not {SIGNATURE_FORMAT}"
    if not _is_text_map(document["files"]):
        return f"signature file {name}: 'files' is not a map of names to hashes"
    if form == SIGNATURE_FORMAT and not _is_text_map(document.get("excluded")):
        return f"signature file {name}: 'excluded' is not a map of patterns to reasons"
    return None


def _read_signature(sig_path: Where) -> tuple[dict[str, Any] | None, str | None]:
    if not sig_path.is_file():
        return None, f"signature missing: {sig_path.name} not found next to the report"
    try:
        document = json.loads(sig_path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:
        return None, f"signature file {sig_path.name} is not valid JSON: {exc}"
    problem = _shape_problem(document, sig_path.name)
    return (None, problem) if problem else (document, None)


def _signed_utc(document: dict[str, Any]) -> tuple[datetime | None, list[str]]:
    if document.get("format") != SIGNATURE_FORMAT:
        return None, []
    try:
        moment = datetime.fromisoformat(str(document.get("signed_utc")))
    except ValueError:
        return None, [f"signature is malformed: signed_utc {document.get('signed_utc')!r}"]
    return (moment.replace(tzinfo=UTC) if moment.tzinfo is None else moment), []


def _check_signature(document: dict[str, Any]) -> tuple[Ed25519PublicKey | None, list[str]]:
    try:
        public = Ed25519PublicKey.from_public_bytes(
            base64.b64decode(str(document["public_key"]), validate=True))
        signature = base64.b64decode(str(document["signature"]), validate=True)
    except (ValueError, binascii.Error) as exc:
        return None, [f"signature file is malformed: {exc}"]
    try:
        public.verify(signature, signed_payload(document))
    except InvalidSignature:
        return public, ["signature invalid: the signed manifest or the signature were altered"]
    reasons = []
    if document.get("fingerprint") not in (None, key_fingerprint(public)):
        reasons.append("signature file fingerprint does not match its public key")
    return public, reasons


def _legacy_compare(report_path: Where, signed: dict[str, str]) -> list[str]:
    """Format 1: the report and :data:`BUNDLE_FILES`, named next to the report."""
    reasons: list[str] = []
    for name in sorted({report_path.name, *BUNDLE_FILES} | set(signed)):
        try:
            member = manifest.member_path(report_path.parent, name)
        except manifest.UnsafeNameError as exc:
            reasons.append(f"signature is malformed: {exc}")
            continue
        if name not in signed:
            if member.is_file():
                reasons.append(f"{name}: present but not covered by the signature")
        elif not member.is_file():
            reasons.append(f"{name}: missing (it was signed)")
        elif manifest.file_sha256(member) != signed[name]:
            reasons.append(f"{name}: modified (sha256 differs from the signed value)")
    return reasons


def _claimed_fingerprints(report_path: Where) -> dict[str, str]:
    """Fingerprints the bundle itself claims: printed in the report and stored in results."""
    claims: dict[str, str] = {}
    match = FINGERPRINT_META.search(report_path.read_bytes())
    if match:
        claims[report_path.name] = match.group(1).decode()
    results_path = report_path.with_name("results.json")
    try:
        signature = json.loads(results_path.read_text()).get("signature") or {}
        if isinstance(signature, dict) and signature.get("fingerprint"):
            claims[results_path.name] = str(signature["fingerprint"])
    except (OSError, ValueError, AttributeError, RecursionError):
        pass  # a missing or altered results.json is reported by the hash comparison
    return claims


def _file_reasons(report_path: Where, document: dict[str, Any]) -> list[str]:
    files = {str(k): str(v) for k, v in document["files"].items()}
    if document.get("format") == SIGNATURE_FORMAT:
        return manifest.compare_members(report_path.parent, files, dict(document["excluded"]))
    return _legacy_compare(report_path, files)


def verify(report_path: Where, trusted: Sequence[TrustedKey] = ()) -> VerifyResult:
    """Check the bundle around ``report_path`` against its ``.sig``; name every difference.

    The signature must verify over its manifest, every file must match it, the key must be
    one of ``trusted`` (valid at the signing time) and the one the certificate prints.
    """
    report_path = locate(report_path)
    if not report_path.is_file():
        return VerifyResult(False, [f"report missing: {report_path} not found"])
    document, problem = _read_signature(signature_path(report_path))
    if document is None:
        return VerifyResult(False, [problem or "signature unreadable"])
    public, reasons = _check_signature(document)
    signed_utc, time_reasons = _signed_utc(document)
    reasons += time_reasons + _file_reasons(report_path, document)
    form = str(document.get("format", LEGACY_FORMAT))
    if public is None:
        return VerifyResult(False, reasons, format=form)
    fingerprint = key_fingerprint(public)
    reasons += [
        f"key mismatch: {name} names key {claimed}, but the signature was made by {fingerprint}"
        for name, claimed in _claimed_fingerprints(report_path).items() if claimed != fingerprint]
    decision = decide(fingerprint, signed_utc,
                      sorted(trusted, key=lambda k: k.signatory is None))
    if decision.reason:
        reasons.append(decision.reason)
    return VerifyResult(not reasons, reasons, fingerprint, decision.key, signed_utc, form)
