"""The signature document of a report bundle: its format, fingerprint and signed bytes.

Signing (:mod:`.signing`) writes this document and verification (:mod:`.verification`)
reads it; both build on the definitions here, so neither imports the other's internals
(signing still offers :func:`~.signing.verify_bundle`, which calls verification).
"""

from __future__ import annotations

import hashlib
import json
import re
from dataclasses import dataclass, field
from datetime import datetime

from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey, Ed25519PublicKey

from aatest.bundle.trust import TrustedKey
from aatest.storage import Where

SIGNATURE_FORMAT = "aatest-signature/2"
LEGACY_FORMAT = "aatest-signature/1"
ALGORITHM = "Ed25519"
#: the files next to the report that a format-1 signature covered (besides the report itself)
BUNDLE_FILES: tuple[str, ...] = ("results.json", "recording.mcap", "report.pdf")
#: the fields of a format-2 signature document that the signature covers
SIGNED_FIELDS: tuple[str, ...] = ("format", "algorithm", "fingerprint", "signed_utc", "files",
                                  "excluded")
#: how a report states the fingerprint of the key that signs it (see the report templates)
FINGERPRINT_META = re.compile(rb'<meta name="aatest-key-fingerprint" content="([0-9a-f]{64})"')


@dataclass
class VerifyResult:
    """Outcome of :func:`~.signing.verify_bundle`; ``reasons`` names every problem found."""

    ok: bool
    reasons: list[str] = field(default_factory=list)
    fingerprint: str | None = None
    trusted: TrustedKey | None = None
    signed_utc: datetime | None = None
    format: str | None = None


def signature_path(report_path: Where) -> Where:
    """Where the detached signature of ``report_path`` lives (``report.html.sig``)."""
    return report_path.with_name(report_path.name + ".sig")


def raw_public_key(public_key: Ed25519PublicKey) -> bytes:
    """The 32 raw bytes of an Ed25519 public key (what the fingerprint and document carry)."""
    return public_key.public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw)


def key_fingerprint(public_key: Ed25519PublicKey | Ed25519PrivateKey) -> str:
    """SHA-256 hex of the raw 32-byte public key; printed on the certificate."""
    if isinstance(public_key, Ed25519PrivateKey):
        public_key = public_key.public_key()
    return hashlib.sha256(raw_public_key(public_key)).hexdigest()


def canonical_bytes(document: dict[str, object]) -> bytes:
    """The exact bytes that are signed: sorted-key, separator-free UTF-8 JSON."""
    return json.dumps(document, sort_keys=True, separators=(",", ":")).encode()


def signed_payload(document: dict[str, object]) -> bytes:
    """What the signature of ``document`` covers: its :data:`SIGNED_FIELDS` (format 2), or its
    ``files`` alone (format 1)."""
    if document.get("format") == SIGNATURE_FORMAT:
        return canonical_bytes({k: document.get(k) for k in SIGNED_FIELDS})
    files = document.get("files")
    return canonical_bytes(files if isinstance(files, dict) else {})
