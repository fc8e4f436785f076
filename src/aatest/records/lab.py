"""The lab profile: who issues the certificates, with which prefix, and how often units return.

One profile serves the records store and the certificate (ISO/IEC 17025 §7.8.2.1: the lab's
name and address, its accreditation, who authorises the certificate). Read from
``--lab lab.yaml`` or ``AATEST_LAB``; without one, a neutral default is used so a single PC can
work out of the box::

    name: Example Calibration Lab
    address: |
      Calibration Street 1
      12345 Example Town, Country
    accreditation:                     # omit when the lab is not accredited
      body: DAkkS
      number: D-K-12345-01-00
      scope: angular acceleration, 0.1–10 Hz, up to 1000 °/s²
    signatories:                       # who authorises the certificate (name, function)
      - {name: Dr. A. Example, function: Head of the calibration laboratory}
    signing_keys:                      # the keys `aatest verify` trusts (aatest keygen prints them)
      - {fingerprint: 3f…(64 hex), signatory: Dr. A. Example, valid_from: 2026-01-01,
         valid_until: 2028-01-01}     # valid_until: first day it no longer signs; omit: open
    certificate_prefix: LAB            # numbers look like LAB-2026-000123
    calibration_interval_months: 12    # next due date = last calibration + interval
    frf_reference_frequency_hz: 1.0    # the FRF point tracked in the history
"""

from __future__ import annotations

import os
from datetime import UTC, date, datetime, time
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from aatest.bundle.trust import TrustedKey
from aatest.engine.simulation import SIMULATION_PREFIX

LAB_ENV = "AATEST_LAB"
#: the key of the lab's identity in ``results.json`` ``metadata`` (written before signing)
METADATA_KEY = "lab"


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Accreditation(_Strict):
    """The lab's accreditation as the certificate states it (ISO/IEC 17025 §7.8.1)."""

    body: str = Field(min_length=1, description="accreditation body, e.g. DAkkS, UKAS, A2LA")
    number: str = Field(min_length=1, description="the lab's accreditation number")
    scope: str = Field("", description="the accredited scope this calibration falls under")


class Signatory(_Strict):
    """A person who authorises certificates (ISO/IEC 17025 §7.8.2.1 o)."""

    name: str = Field(min_length=1, description="full name as printed")
    function: str = Field(min_length=1, description="role, e.g. Head of the calibration lab")


def _midnight_utc(day: date | None) -> datetime | None:
    return None if day is None else datetime.combine(day, time(0), tzinfo=UTC)


class SigningKey(_Strict):
    """A key the lab signs certificates with: who holds it and when it may sign.

    ``aatest verify`` trusts a signature only from a key listed here (or given with
    ``--public-key``), and only when the signing time lies in ``[valid_from, valid_until)``;
    retiring or revoking a key is setting ``valid_until``.
    """

    fingerprint: str = Field(pattern=r"^[0-9a-f]{64}$",
                             description="SHA-256 hex of the public key (aatest keygen prints it)")
    signatory: str = Field(min_length=1, description="who holds the key (a signatory's name)")
    valid_from: date = Field(description="first day (UTC) the key signs")
    valid_until: date | None = Field(None, description="first day (UTC) it no longer signs")

    @model_validator(mode="after")
    def _ordered(self) -> SigningKey:
        if self.valid_until is not None and self.valid_until <= self.valid_from:
            raise ValueError(f"valid_until {self.valid_until} is not after valid_from "
                             f"{self.valid_from}")
        return self

    def trusted(self, source: str) -> TrustedKey:
        """This entry as the verifier's :class:`TrustedKey`."""
        return TrustedKey(self.fingerprint, source, self.signatory,
                          _midnight_utc(self.valid_from), _midnight_utc(self.valid_until))


class LabProfile(_Strict):
    """A calibration lab as the records store and the certificate need to know it."""

    name: str = Field("aatest lab", min_length=1,
                      description="lab name on records and certificates")
    address: str = Field("", description="postal address printed under the lab's name")
    accreditation: Accreditation | None = Field(None, description="none: not accredited")
    signatories: tuple[Signatory, ...] = Field(
        (), description="who authorises the certificates; the first one signs")
    signing_keys: tuple[SigningKey, ...] = Field(
        (), description="the keys whose signatures `aatest verify` accepts, with validity")
    certificate_prefix: str = Field(
        "LAB", pattern=r"^[A-Z0-9][A-Z0-9_]{0,15}$", description="prefix of certificate numbers")
    calibration_interval_months: int = Field(12, ge=1, le=120, description="recall interval")
    frf_reference_frequency_hz: float = Field(
        1.0, gt=0, description="frequency whose FRF gain is tracked over time, Hz")

    @field_validator("certificate_prefix")
    @classmethod
    def _not_the_simulation_series(cls, prefix: str) -> str:
        if prefix == SIMULATION_PREFIX:
            raise ValueError(f"{SIMULATION_PREFIX!r} is the series of simulations, which are "
                             "never calibrations; choose another prefix")
        return prefix

    @model_validator(mode="after")
    def _key_holders_sign(self) -> LabProfile:
        names = {s.name for s in self.signatories}
        for key in self.signing_keys:
            if names and key.signatory not in names:
                raise ValueError(f"signing key {key.fingerprint[:12]}…: signatory "
                                 f"{key.signatory!r} is not one of the signatories")
        return self

    def trusted_keys(self, source: str) -> list[TrustedKey]:
        """The verifier's trusted keys from this profile (``source`` names the profile)."""
        return [key.trusted(source) for key in self.signing_keys]

    def certificate_identity(self) -> dict[str, Any]:
        """What the certificate prints about the lab (stored in the results' metadata);
        ``default_profile`` says no profile was given (the certificate then says so)."""
        return {"name": self.name, "address": self.address,
                "accreditation": (self.accreditation.model_dump()
                                  if self.accreditation is not None else None),
                "signatories": [s.model_dump() for s in self.signatories],
                "calibration_interval_months": self.calibration_interval_months,
                "default_profile": self == LabProfile()}


def lab_path(path: Path | None = None) -> Path | None:
    """The profile file in use: ``path``, else ``AATEST_LAB``, else none."""
    return path or (Path(os.environ[LAB_ENV]) if os.environ.get(LAB_ENV) else None)


def load_lab(path: Path | None = None) -> LabProfile:
    """The lab profile from ``path``, else ``AATEST_LAB``, else the defaults.

    YAML errors are reported as ``FILE:LINE:COLUMN: field: message`` (exit 2) by the engine's
    model loader.
    """
    from aatest.positioned_yaml import load_model_file

    chosen = lab_path(path)
    if chosen is None:
        return LabProfile()
    return load_model_file(chosen, LabProfile)
