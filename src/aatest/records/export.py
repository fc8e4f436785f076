"""``aatest records export --csv``: records as one CSV row each, quantities as columns."""

from __future__ import annotations

import csv
from collections.abc import Sequence
from pathlib import Path

from aatest.records.history import quantity_names
from aatest.records.models import CalibrationRecord

BASE_COLUMNS = ("certificate_number", "model", "serial", "procedure", "calibrated_utc",
                "overall_verdict", "operator", "lab", "command", "bundle", "key_fingerprint")


def write_csv(path: Path, records: Sequence[CalibrationRecord]) -> Path:
    """Write ``records``; per quantity ``NAME``, columns ``NAME``, ``NAME_U`` and ``NAME_unit``."""
    names = quantity_names(records)
    header = [*BASE_COLUMNS, *[f"{n}{suffix}" for n in names for suffix in ("", "_U", "_unit")]]
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(header)
        for record in records:
            base = record.model_dump(mode="json", include=set(BASE_COLUMNS))
            row: list[object] = [
                base.get(c) if base.get(c) is not None else "" for c in BASE_COLUMNS]
            for name in names:
                q = record.quantities.get(name)
                row += ["", "", ""] if q is None else [
                    q.value, "" if q.expanded_uncertainty is None else q.expanded_uncertainty,
                    q.unit]
            writer.writerow(row)
    return path
