"""Ed25519 signatures over a report bundle: every file of its directory, by SHA-256.

A certificate is only worth what it proves: the signature covers a manifest of the SHA-256 of
every file below the report's directory (report, ``results.json``, ``recording.mcap``,
``run_state.json``, ``steps/*.mcap`` …), the files left out and why, and the signing time.
:func:`verify_bundle` names every changed, missing or added file, and accepts the signature only
from a key the verifier trusts (:mod:`.trust`), never from the key the signature carries.

Signature file ``<report>.sig`` (JSON, format 2)::

    {"format": "aatest-signature/2", "algorithm": "Ed25519",
     "fingerprint": "<sha256 hex of the raw public key>", "public_key": "<base64 raw>",
     "signed_utc": "2026-11-26T08:00:00+00:00",
     "files": {"report.html": "<sha256 hex>", "steps/0001-static.mcap": ..., ...},
     "excluded": {"*.sig": "<why such files are not signed>", ...},
     "signature": "<base64 Ed25519 signature over the canonical JSON of the other fields>"}

Format 1 signatures (``files`` only, signed alone) are still verified, over the files they
named; the output says which format was checked.
"""

from __future__ import annotations

import base64
import json
import os
import stat
from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import Path

from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey, Ed25519PublicKey

from aatest.bundle import manifest
from aatest.bundle.signature_format import (
    ALGORITHM,
    BUNDLE_FILES,
    FINGERPRINT_META,
    LEGACY_FORMAT,
    SIGNATURE_FORMAT,
    SIGNED_FIELDS,
    VerifyResult,
    canonical_bytes,
    key_fingerprint,
    raw_public_key,
    signature_path,
    signed_payload,
)
from aatest.bundle.trust import TrustedKey
from aatest.bundle.verification import verify
from aatest.engine.errors import InputError
from aatest.storage import Where, locate

# the signature document's definitions live in .signature_format, shared with verification;
# they stay importable from here
__all__ = ["ALGORITHM", "BUNDLE_FILES", "FINGERPRINT_META", "LEGACY_FORMAT", "SIGNATURE_FORMAT",
           "SIGNED_FIELDS", "SigningError", "VerifyResult", "bundle_hashes", "canonical_bytes",
           "file_sha256", "generate_keypair", "key_fingerprint", "load_private_key",
           "load_public_key", "public_key_path", "sign_bundle", "signature_path",
           "signed_payload", "trusted_public_key", "verify_bundle"]

#: SHA-256 of one file, as the manifest hashes it (kept here for callers of format 1)
file_sha256 = manifest.file_sha256



class SigningError(InputError):
    """A key file is missing, unreadable, of the wrong type, too open or wrongly protected."""


def public_key_path(key_path: Path) -> Path:
    """Where :func:`generate_keypair` writes the public key (``KEYFILE.pub``)."""
    return key_path.with_name(key_path.name + ".pub")


def _create_exclusive(path: Path, data: bytes, mode: int) -> None:
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0),
                     mode)
    except OSError as exc:
        raise SigningError(f"{path}: cannot create key file: {exc.strerror}") from exc
    with os.fdopen(fd, "wb") as handle:
        handle.write(data)
    os.chmod(path, mode)  # umask cannot widen it, but be explicit


def generate_keypair(key_path: Path, passphrase: str | None = None) -> str:
    """Create an Ed25519 key pair: private PEM at ``key_path`` (mode 0600), public at ``.pub``.

    The private key is encrypted with ``passphrase`` (PKCS#8, the best available scheme);
    ``None`` writes it unencrypted, which the CLI allows only on ``--no-passphrase``. Refuses
    to overwrite either file (or a symbolic link there, even a dangling one), so a signing
    identity is never lost by a typo. Returns the key fingerprint.
    """
    key_path = Path(key_path)
    pub_path = public_key_path(key_path)
    for existing in (key_path, pub_path):
        if os.path.lexists(existing):
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
    _create_exclusive(key_path, pem, 0o600)
    _create_exclusive(pub_path, key.public_key().public_bytes(
        serialization.Encoding.PEM, serialization.PublicFormat.SubjectPublicKeyInfo), 0o644)
    return key_fingerprint(key)


def _refuse_open_permissions(path: Path) -> None:
    """A private key readable by group or others is not private: refuse it (POSIX only)."""
    if os.name != "posix":
        return
    mode = stat.S_IMODE(path.stat().st_mode)
    if mode & 0o077:
        raise SigningError(f"{path}: private key is accessible by group or others (mode "
                           f"{mode:04o}); restrict it with: chmod 600 {path}")


def load_private_key(path: Path, passphrase: str | None = None) -> Ed25519PrivateKey:
    """Read a PEM private key written by :func:`generate_keypair` (or any Ed25519 PKCS8 PEM).

    Raises
    ------
    SigningError
        Unreadable, readable by group/others, wrong passphrase, or not an Ed25519 key.
    """
    path = Path(path)
    try:
        _refuse_open_permissions(path)
        data = path.read_bytes()
    except OSError as exc:
        raise SigningError(f"{path}: cannot read signing key: {exc.strerror}") from exc
    try:
        key = serialization.load_pem_private_key(
            data, passphrase.encode() if passphrase else None
        )
    except TypeError as exc:  # encrypted key without passphrase, or passphrase for a plain key
        raise SigningError(f"{path}: {exc} (check the passphrase: AATEST_SIGNING_PASSPHRASE)"
                           ) from exc
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


def trusted_public_key(path: Path) -> TrustedKey:
    """The key of a public key file as a trusted key (``verify --public-key FILE``)."""
    return TrustedKey(key_fingerprint(load_public_key(path)), source=f"--public-key {path}")


def bundle_hashes(report_path: Where) -> dict[str, str]:
    """SHA-256 of every file of the bundle around ``report_path`` that a signature covers
    (the report itself always, even where an exclusion names its kind: a diagnosis)."""
    report_path = locate(report_path)
    hashes = manifest.manifest_hashes(report_path.parent)
    hashes[report_path.name] = manifest.file_sha256(report_path)
    return hashes


def sign_bundle(report_path: Where, private_key: Ed25519PrivateKey) -> Where:
    """Sign the bundle around ``report_path``; write and return ``<report>.sig``.

    ``results.json`` must exist next to the report; every other file below the report's
    directory is signed too, except those :data:`manifest.EXCLUSIONS` names (with the reason).
    A bundle on object storage is signed in place: its objects are hashed as streamed.
    """
    report_path = locate(report_path)
    if not report_path.is_file():
        raise SigningError(f"{report_path}: report to sign does not exist")
    if not report_path.with_name("results.json").is_file():
        raise SigningError(f"{report_path.parent}: no results.json next to the report to sign")
    _files, links = manifest.bundle_members(report_path.parent)
    if links:
        raise SigningError(f"{report_path.parent}: symbolic link(s) {', '.join(links)} in the "
                           "bundle; a signature covers files only")
    document: dict[str, object] = {
        "format": SIGNATURE_FORMAT,
        "algorithm": ALGORITHM,
        "fingerprint": key_fingerprint(private_key),
        "public_key": base64.b64encode(raw_public_key(private_key.public_key())).decode(),
        "signed_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        "files": bundle_hashes(report_path),
        "excluded": dict(manifest.EXCLUSIONS),
    }
    document["signature"] = base64.b64encode(private_key.sign(signed_payload(document))).decode()
    sig_path = signature_path(report_path)
    sig_path.write_text(json.dumps(document, indent=2, sort_keys=True) + "\n")
    return sig_path


def verify_bundle(report_path: Where, trusted: Sequence[TrustedKey] = ()) -> VerifyResult:
    """Check the bundle around ``report_path``: see :func:`.verification.verify`."""
    return verify(report_path, trusted)
