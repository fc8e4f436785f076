"""Which signing keys a verifier trusts: configured by the lab, never taken from the bundle.

A signature file carries its public key, so anyone can make a bundle that is consistent with
itself. What makes a certificate genuine is that the key belongs to the lab: the lab profile
lists its keys by fingerprint, with the signatory who holds each and the period the key is
valid (``signing_keys``), or the verifier names a public key file (``--public-key``). A
signature made outside the key's validity period, or by a key in neither list, is refused.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime


@dataclass(frozen=True)
class TrustedKey:
    """A key the verifier accepts, and what it says about who signed."""

    fingerprint: str
    source: str
    signatory: str | None = None
    valid_from_utc: datetime | None = None
    valid_until_utc: datetime | None = None

    def period(self) -> str:
        """The validity period as printed (``2026-01-01 – 2027-01-01``, open ends as ``…``)."""
        start = f"{self.valid_from_utc:%Y-%m-%d}" if self.valid_from_utc else "…"
        end = f"{self.valid_until_utc:%Y-%m-%d}" if self.valid_until_utc else "…"
        return f"{start} – {end}"

    def valid_at(self, moment: datetime) -> bool:
        """Whether ``moment`` lies in ``[valid_from, valid_until)``."""
        if self.valid_from_utc is not None and moment < self.valid_from_utc:
            return False
        return self.valid_until_utc is None or moment < self.valid_until_utc


@dataclass(frozen=True)
class TrustDecision:
    """Whether the signing key is trusted: the matching entry, or the reason it is not."""

    key: TrustedKey | None
    reason: str | None = None


def no_trust_configured(fingerprint: str) -> str:
    """The reason given when the verifier was told to trust no key at all."""
    return (f"signed by key {fingerprint}, but no key is trusted: give --public-key FILE, or "
            "list the lab's keys under signing_keys in the lab profile (--lab / AATEST_LAB)")


def decide(fingerprint: str, signed_utc: datetime | None,
           trusted: Sequence[TrustedKey]) -> TrustDecision:
    """Trust ``fingerprint`` if an entry of ``trusted`` names it and covers ``signed_utc``.

    ``signed_utc`` is the signing time stated in the signed manifest; a signature without one
    (format 1) is judged at the present moment, the stricter choice.
    """
    if not trusted:
        return TrustDecision(None, no_trust_configured(fingerprint))
    moment = signed_utc.astimezone(UTC) if signed_utc is not None else datetime.now(UTC)
    entries = [k for k in trusted if k.fingerprint == fingerprint]
    if not entries:
        sources = sorted({k.source for k in trusted})
        return TrustDecision(None, f"signed by key {fingerprint}, which is not trusted "
                                   f"(trusted keys: {', '.join(sources)})")
    for entry in entries:
        if entry.valid_at(moment):
            return TrustDecision(entry)
    entry = entries[0]
    who = f" of {entry.signatory}" if entry.signatory else ""
    return TrustDecision(None, f"key {fingerprint}{who} is valid {entry.period()} "
                               f"({entry.source}), but the bundle was signed "
                               f"{moment:%Y-%m-%d %H:%M} UTC")
