"""What ``aatest verify`` trusts and what it says about who signed.

The trusted keys come from configuration only: the lab profile's ``signing_keys``
(``--lab`` / ``AATEST_LAB``) and a public key file given with ``--public-key``. The lines
printed for a valid bundle name the key by its full fingerprint, the signatory who holds it
(from the lab profile) and the signatory the certificate itself names, so a reader can see
both the cryptographic and the organisational claim.
"""

from __future__ import annotations

import json
from pathlib import Path

from aatest.bundle.signing import VerifyResult, trusted_public_key
from aatest.bundle.trust import TrustedKey
from aatest.records.lab import lab_path, load_lab


def trusted_keys(lab: Path | None, public_key: Path | None) -> list[TrustedKey]:
    """The lab profile's signing keys (if a profile is configured) and ``public_key``."""
    keys: list[TrustedKey] = []
    chosen = lab_path(lab)
    if chosen is not None:
        keys += load_lab(chosen).trusted_keys(f"lab profile {chosen}")
    if public_key is not None:
        keys.append(trusted_public_key(public_key))
    return keys


def certificate_signatory(report: Path) -> str | None:
    """The signatory the certificate names (``results.json`` → ``metadata.lab.signatories[0]``)."""
    try:
        document = json.loads(report.with_name("results.json").read_text(encoding="utf-8"))
        first = document["metadata"]["lab"]["signatories"][0]
        return str(first["name"]) if isinstance(first, dict) and first.get("name") else None
    except (OSError, ValueError, KeyError, IndexError, TypeError, RecursionError):
        return None


def signer_lines(result: VerifyResult, report: Path) -> list[str]:
    """``key:`` and ``signatory:`` lines for a bundle whose signature was accepted."""
    key = result.trusted
    lines = [f"key:       {result.fingerprint} ({key.source if key else 'untrusted'}"
             + (f", valid {key.period()})" if key and key.valid_from_utc else ")")]
    stated = certificate_signatory(report)
    if key is not None and key.signatory:
        also = f"; the certificate names {stated}" if stated and stated != key.signatory else ""
        lines.append(f"signatory: {key.signatory} (holder of the key{also})")
    elif stated:
        lines.append(f"signatory: {stated} (as the certificate states; the trusted key names "
                     "no holder)")
    else:
        lines.append("signatory: none named (neither the certificate nor the trusted key "
                     "names one)")
    return lines
