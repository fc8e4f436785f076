"""Typed views of the records: what is registered and what a query returns."""

from __future__ import annotations

from datetime import datetime
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from aatest.engine.simulation import Kind


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class QuantityRecord(_Strict):
    """One key result as stored: value ± expanded uncertainty (``None`` if not stated)."""

    value: float
    expanded_uncertainty: float | None = None
    unit: str


class Registration(_Strict):
    """Everything one registration stores; built from ``results.json`` and the bundle."""

    model: str = Field(description="sensor model")
    serial: str = Field(description="sensor unit serial")
    certificate_number: str | None = None
    command: str = Field(description="run | analyze | report | diagnose")
    kind: Kind = Field("calibration", description="simulation: a run with a simulated part")
    procedure: str
    procedure_sha256: str | None = None
    rig: dict[str, Any] = Field(default_factory=dict)
    plugin_versions: dict[str, str] = Field(default_factory=dict)
    operator: str | None = None
    lab: str
    calibrated_utc: datetime
    overall_verdict: str = "none"
    verdicts: list[dict[str, Any]] = Field(default_factory=list)
    results: dict[str, Any] = Field(default_factory=dict)
    bundle: str = Field(description="absolute path of the bundle's main file (report)")
    key_fingerprint: str | None = None
    files: dict[str, str] = Field(default_factory=dict, description="file name → SHA-256 hex")
    quantities: dict[str, QuantityRecord] = Field(default_factory=dict)


class CalibrationRecord(_Strict):
    """One stored record (a query result); ``superseded_by`` is set once a newer one replaces it."""

    id: int
    model: str
    serial: str
    certificate_number: str | None
    supersedes_id: int | None
    superseded_by: int | None
    command: str
    kind: Kind = "calibration"
    procedure: str
    procedure_sha256: str | None
    operator: str | None
    lab: str
    calibrated_utc: datetime
    registered_utc: datetime
    overall_verdict: str
    verdicts: list[dict[str, Any]]
    bundle: str
    key_fingerprint: str | None
    files: dict[str, str]
    quantities: dict[str, QuantityRecord]
    rig: dict[str, Any]
    plugin_versions: dict[str, str]

    def history_json(self) -> dict[str, Any]:
        """The ``aatest history --json`` entry (docs/interfaces.md §1)."""
        return {
            "certificate_number": self.certificate_number,
            "procedure": self.procedure,
            "calibrated_utc": self.calibrated_utc.isoformat(timespec="seconds"),
            "overall_verdict": self.overall_verdict,
            "kind": self.kind,
            "quantities": {k: q.model_dump() for k, q in self.quantities.items()},
            "bundle": self.bundle,
        }


class RecordFilter(_Strict):
    """A query over records; every field left ``None`` matches everything."""

    serial: str | None = None
    model: str | None = None
    procedure: str | None = None
    verdict: str | None = None
    since_utc: datetime | None = None
    until_utc: datetime | None = None
    include_superseded: bool = False
    #: simulations are kept apart: only listed when asked (``--include-simulations``)
    include_simulations: bool = False
