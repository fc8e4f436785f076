"""What the fleet pages read from the records store: calibrations, their rig, their findings.

A record keeps the run's results; the rig a calibration ran on is named by the turntable's
reported serial (``metadata.table_serial``), else by its plugins and a short hash of the rig
description (two rigs built alike from the same YAML share it). Simulations are left out
unless asked for, as ``aatest history`` does: a simulation calibrates nothing.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any

from sqlalchemy import select

from aatest.records.models import CalibrationRecord, RecordFilter
from aatest.records.store import RecordStore
from aatest.records.tables import calibrations

#: what the run metadata says when a turntable reports no serial
_UNREPORTED = frozenset({"", "unreported", "none"})
#: the name ``aatest diagnose --json`` is pointed at beside its report (docs/fleet.md)
DIAGNOSIS_JSON = "diagnosis.json"
_HASH_CHARS = 8


@dataclass(frozen=True)
class FleetRecord:
    """One stored calibration or diagnosis with the rig it ran on."""

    record: CalibrationRecord
    rig: str
    #: as-left values an adjustment stated (``metadata.adjustment.as_left``), by quantity
    as_left: dict[str, float] = field(default_factory=dict)


def rig_label(results: Mapping[str, Any]) -> str:
    """The rig a stored result ran on (see the module docstring)."""
    meta = results.get("metadata") or {}
    serial = str(meta.get("table_serial") or "").strip()
    if serial.lower() not in _UNREPORTED:
        return serial
    rig = {k: v for k, v in (results.get("rig") or {}).items() if k != "capabilities"}
    digest = hashlib.sha256(json.dumps(rig, sort_keys=True, default=str).encode()).hexdigest()
    plugins = "/".join(str((rig.get(kind) or {}).get("plugin", "?"))
                       for kind in ("turntable", "daq"))
    return f"{plugins} #{digest[:_HASH_CHARS]}"


def _as_left(results: Mapping[str, Any]) -> dict[str, float]:
    stated = (results.get("metadata") or {}).get("adjustment") or {}
    as_left = stated.get("as_left") if stated.get("made") else None
    if not isinstance(as_left, Mapping):
        return {}
    return {str(k): float(v) for k, v in as_left.items() if isinstance(v, (int, float))}


def _stored_results(store: RecordStore, ids: Sequence[int]) -> dict[int, Mapping[str, Any]]:
    """The stored results of ``ids`` in one query (no validation: only two keys are read)."""
    with store.engine.connect() as connection:
        rows = connection.execute(select(calibrations.c.id, calibrations.c.results).where(
            calibrations.c.id.in_(list(ids)))).all()
    return {int(row.id): row.results or {} for row in rows}


def load(store: RecordStore, model: str | None = None, serial: str | None = None,
         since_utc: datetime | None = None, include_simulations: bool = False
         ) -> list[FleetRecord]:
    """Current records (calibrations and diagnoses) matching the filter, oldest first."""
    records = store.query(RecordFilter(model=model, serial=serial, since_utc=since_utc,
                                       include_simulations=include_simulations))
    stored = _stored_results(store, [r.id for r in records])
    return [FleetRecord(r, rig_label(stored.get(r.id, {})), _as_left(stored.get(r.id, {})))
            for r in records]


def calibrations_of(records: Sequence[FleetRecord]) -> list[FleetRecord]:
    """The calibrations (no diagnoses) among ``records``."""
    return [f for f in records if f.record.command != "diagnose"]


def diagnoses_of(records: Sequence[FleetRecord]) -> list[FleetRecord]:
    """The registered diagnoses among ``records``."""
    return [f for f in records if f.record.command == "diagnose"]


def stored_findings(record: CalibrationRecord) -> list[dict[str, Any]] | None:
    """The findings of a registered diagnosis: its JSON bundle, else the ``diagnosis.json``
    beside its report; None when neither is readable (the page says so)."""
    bundle = Path(record.bundle)
    for candidate in (bundle, bundle.with_name(DIAGNOSIS_JSON)):
        if candidate.suffix != ".json" or not candidate.is_file():
            continue
        try:
            document = json.loads(candidate.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        if isinstance(document, dict) and isinstance(document.get("findings"), list):
            return [f for f in document["findings"] if isinstance(f, dict) and "effect" in f]
    return None


def diagnose_recording(record: CalibrationRecord) -> list[dict[str, Any]]:
    """Run the diagnose pipeline on the recording of a calibration's run directory; the
    findings' names (effect, channel, attribution), which is all the fleet page compares."""
    from aatest.diagnose.pipeline import diagnose_dataset
    from aatest.recording import read_dataset

    document = diagnose_dataset(read_dataset(Path(record.bundle).parent))
    return [{key: str(f[key]) for key in ("effect", "channel", "attributed_to") if key in f}
            for f in document["findings"]]
