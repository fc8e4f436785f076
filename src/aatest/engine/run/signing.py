"""Ed25519 signatures over a report bundle (report, ``results.json``, ``recording.mcap``).

A certificate is only worth what it proves: the signature covers the SHA-256 of every file of
the bundle, so changing any byte of the report, the results or the raw recording, or re-signing
with another key, is detected by :func:`verify_bundle`, which names exactly what changed.

Signature file ``<report>.sig`` (JSON)::

    {"format": "aatest-signature/1", "algorithm": "Ed25519",
     "fingerprint": "<sha256 hex of the raw public key>", "public_key": "<base64 raw>",
     "files": {"report.html": "<sha256 hex>", "results.json": ..., "recording.mcap": ...},
     "signature": "<base64 Ed25519 signature over the canonical JSON of 'files'>"}
"""

from __future__ import annotations

import base64
import hashlib
import json
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

from cryptography.exceptions import InvalidSignature
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey, Ed25519PublicKey

from aatest.engine.errors import InputError

SIGNATURE_FORMAT = "aatest-signature/1"
ALGORITHM = "Ed25519"
#: the files next to the report that the signature covers (besides the report itself)
BUNDLE_FILES: tuple[str, ...] = ("results.json", "recording.mcap", "report.pdf")
_CHUNK_BYTES = 1 << 20
#: how a report states the fingerprint of the key that signs it (see the report templates)
FINGERPRINT_META = re.compile(rb'<meta name="aatest-key-fingerprint" content="([0-9a-f]{64})"')


class SigningError(InputError):
    """A key file is missing, unreadable, of the wrong type or protected by another passphrase."""


@dataclass
class VerifyResult:
    """Outcome of :func:`verify_bundle`; ``reasons`` names every problem found."""

    ok: bool
    reasons: list[str] = field(default_factory=list)
    fingerprint: str | None = None


def signature_path(report_path: Path) -> Path:
    """Where the detached signature of ``report_path`` lives (``report.html.sig``)."""
    return report_path.with_name(report_path.name + ".sig")


def public_key_path(key_path: Path) -> Path:
    """Where :func:`generate_keypair` writes the public key (``KEYFILE.pub``)."""
    return key_path.with_name(key_path.name + ".pub")


def file_sha256(path: Path) -> str:
    """SHA-256 hex digest of a file, read in 1 MiB chunks (recordings can be large)."""
    digest = hashlib.sha256()
    with path.open("rb") as handle:
        for chunk in iter(lambda: handle.read(_CHUNK_BYTES), b""):
            digest.update(chunk)
    return digest.hexdigest()


def _raw_public(public_key: Ed25519PublicKey) -> bytes:
    return public_key.public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw)


def key_fingerprint(public_key: Ed25519PublicKey | Ed25519PrivateKey) -> str:
    """SHA-256 hex of the raw 32-byte public key; printed on the certificate."""
    if isinstance(public_key, Ed25519PrivateKey):
        public_key = public_key.public_key()
    return hashlib.sha256(_raw_public(public_key)).hexdigest()


def generate_keypair(key_path: Path, passphrase: str | None = None) -> str:
    """Create an Ed25519 key pair: private PEM at ``key_path`` (mode 0600), public at ``.pub``.

    Refuses to overwrite either file, so a signing identity is never lost by a typo.
    Returns the key fingerprint.
    """
    key_path = Path(key_path)
    pub_path = public_key_path(key_path)
    for existing in (key_path, pub_path):
        if existing.exists() or existing.is_symlink():  # a dangling link would be followed
            raise SigningError(f"{existing}: already exists; refusing to overwrite a key file")
    key = Ed25519PrivateKey.generate()
    encryption: serialization.KeySerializationEncryption = (
        serialization.BestAvailableEncryption(passphrase.encode())
        if passphrase
        else serialization.NoEncryption()
    )
    pem = key.private_bytes(
        serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, encryption
    )
    try:
        fd = os.open(key_path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o600)
    except OSError as exc:
        raise SigningError(f"{key_path}: cannot create the key file: {exc.strerror}") from exc
    with os.fdopen(fd, "wb") as handle:
        handle.write(pem)
    os.chmod(key_path, 0o600)  # umask cannot widen it, but be explicit
    pub_path.write_bytes(
        key.public_key().public_bytes(
            serialization.Encoding.PEM, serialization.PublicFormat.SubjectPublicKeyInfo
        )
    )
    return key_fingerprint(key)


def load_private_key(path: Path, passphrase: str | None = None) -> Ed25519PrivateKey:
    """Read a PEM private key written by :func:`generate_keypair` (or any Ed25519 PKCS8 PEM)."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise SigningError(f"{path}: cannot read signing key: {exc.strerror}") from exc
    try:
        key = serialization.load_pem_private_key(
            data, passphrase.encode() if passphrase else None
        )
    except TypeError as exc:  # encrypted key without passphrase, or passphrase for a plain key
        raise SigningError(f"{path}: {exc} (check the passphrase)") from exc
    except ValueError as exc:
        raise SigningError(f"{path}: not a usable private key or wrong passphrase") from exc
    if not isinstance(key, Ed25519PrivateKey):
        raise SigningError(f"{path}: key is {type(key).__name__}, aatest signs with Ed25519 only")
    return key


def load_public_key(path: Path) -> Ed25519PublicKey:
    """Read a PEM public key (``KEYFILE.pub``)."""
    path = Path(path)
    try:
        key = serialization.load_pem_public_key(path.read_bytes())
    except OSError as exc:
        raise SigningError(f"{path}: cannot read public key: {exc.strerror}") from exc
    except ValueError as exc:
        raise SigningError(f"{path}: not a PEM public key") from exc
    if not isinstance(key, Ed25519PublicKey):
        raise SigningError(f"{path}: key is {type(key).__name__}, expected Ed25519")
    return key


def bundle_hashes(report_path: Path) -> dict[str, str]:
    """SHA-256 of the report and of every :data:`BUNDLE_FILES` member present next to it."""
    report_path = Path(report_path)
    hashes = {report_path.name: file_sha256(report_path)}
    for name in BUNDLE_FILES:
        member = report_path.with_name(name)
        if member.is_file():
            hashes[name] = file_sha256(member)
    return hashes


def canonical_bytes(hashes: dict[str, str]) -> bytes:
    """The exact bytes that are signed: sorted-key, separator-free UTF-8 JSON."""
    return json.dumps(hashes, sort_keys=True, separators=(",", ":")).encode()


def sign_bundle(report_path: Path, private_key: Ed25519PrivateKey) -> Path:
    """Sign the bundle around ``report_path``; write and return ``<report>.sig``.

    ``results.json`` must exist next to the report; the recording is included when present
    (an ``aatest report`` of an import directory has none).
    """
    report_path = Path(report_path)
    if not report_path.is_file():
        raise SigningError(f"{report_path}: report to sign does not exist")
    if not report_path.with_name("results.json").is_file():
        raise SigningError(f"{report_path.parent}: no results.json next to the report to sign")
    hashes = bundle_hashes(report_path)
    document = {
        "format": SIGNATURE_FORMAT,
        "algorithm": ALGORITHM,
        "fingerprint": key_fingerprint(private_key),
        "public_key": base64.b64encode(_raw_public(private_key.public_key())).decode(),
        "files": hashes,
        "signature": base64.b64encode(private_key.sign(canonical_bytes(hashes))).decode(),
    }
    sig_path = signature_path(report_path)
    sig_path.write_text(json.dumps(document, indent=2, sort_keys=True) + "\n")
    return sig_path


def _read_signature(sig_path: Path) -> tuple[dict[str, object] | None, str | None]:
    if not sig_path.is_file():
        return None, f"signature missing: {sig_path.name} not found next to the report"
    try:
        document = json.loads(sig_path.read_text())
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        return None, f"signature file {sig_path.name} is not valid JSON: {exc}"
    needed = ("algorithm", "public_key", "files", "signature")
    if not isinstance(document, dict) or any(k not in document for k in needed):
        return None, f"signature file {sig_path.name} lacks one of {', '.join(needed)}"
    if document["algorithm"] != ALGORITHM:
        return None, f"signature algorithm {document['algorithm']!r} is not {ALGORITHM}"
    return document, None


def _compare_hashes(report_path: Path, signed: dict[str, str]) -> list[str]:
    reasons: list[str] = []
    names = [report_path.name, *BUNDLE_FILES]
    for name in sorted(set(names) | set(signed)):
        if Path(name).is_absolute() or ".." in Path(name).parts or name in ("", "."):
            reasons.append(f"{name!r}: the signature names a file outside the bundle")
            continue
        member = report_path.parent / name
        if name not in signed:
            if member.is_file():
                reasons.append(f"{name}: present but not covered by the signature")
            continue
        if not member.is_file():
            reasons.append(f"{name}: missing (it was signed)")
        elif file_sha256(member) != signed[name]:
            reasons.append(f"{name}: modified (sha256 differs from the signed value)")
    return reasons


def _check_signature(document: dict[str, object]) -> tuple[Ed25519PublicKey | None, list[str]]:
    try:
        public = Ed25519PublicKey.from_public_bytes(base64.b64decode(str(document["public_key"])))
        signature = base64.b64decode(str(document["signature"]))
    except ValueError as exc:
        return None, [f"signature file is malformed: {exc}"]
    files = document["files"]
    if not isinstance(files, dict):
        return public, ["signature file is malformed: 'files' is not a mapping"]
    try:
        public.verify(signature, canonical_bytes(files))
    except InvalidSignature:
        return public, ["signature invalid: the signed file hashes or the signature were altered"]
    reasons = []
    if document.get("fingerprint") not in (None, key_fingerprint(public)):
        reasons.append("signature file fingerprint does not match its public key")
    return public, reasons


def _claimed_fingerprints(report_path: Path) -> dict[str, str]:
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
    except (OSError, ValueError, AttributeError):
        pass  # a missing or altered results.json is reported by the hash comparison
    return claims


def _key_reasons(report_path: Path, fingerprint: str, trusted: Path | None) -> list[str]:
    reasons = [
        f"key mismatch: {name} names key {claimed}, but the signature was made by {fingerprint}"
        for name, claimed in _claimed_fingerprints(report_path).items()
        if claimed != fingerprint
    ]
    if trusted is not None:
        trusted_fp = key_fingerprint(load_public_key(trusted))
        if trusted_fp != fingerprint:
            reasons.append(
                f"key mismatch: signed by {fingerprint}, trusted key {trusted.name} is {trusted_fp}"
            )
    return reasons


def verify_bundle(report_path: Path, public_key_path: Path | None = None) -> VerifyResult:
    """Check the bundle around ``report_path`` against its ``.sig``; name every difference.

    The signing key must be the one whose fingerprint the certificate prints (and
    ``results.json`` records), so a bundle re-signed with another key fails. With
    ``public_key_path`` the bundle must also have been signed by that trusted key.
    """
    report_path = Path(report_path)
    if not report_path.is_file():
        return VerifyResult(False, [f"report missing: {report_path} not found"])
    document, problem = _read_signature(signature_path(report_path))
    if document is None:
        return VerifyResult(False, [problem or "signature unreadable"])
    public, reasons = _check_signature(document)
    files = document["files"]
    if isinstance(files, dict):
        reasons += _compare_hashes(report_path, {str(k): str(v) for k, v in files.items()})
    if public is None:
        return VerifyResult(False, reasons)
    fingerprint = key_fingerprint(public)
    reasons += _key_reasons(report_path, fingerprint, public_key_path)
    return VerifyResult(not reasons, reasons, fingerprint)
