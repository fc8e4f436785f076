"""A unit's history for the page ``/units/SERIAL``: every record of its serial, oldest first.

The records are read from the store the station registers its runs in (``--records``, else
``AATEST_RECORDS`` or the user's file, as ``aatest run``), simulations included and marked as
such (the twin's runs are simulations, never calibrations). Each record lists its key
quantities by name and unit symbol from the quantity registry, value and expanded U rounded per
GUM 7.2.6, and links its run files when its bundle lies in the station's runs directory.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from aatest.engine.errors import InputError
from aatest.results.quantities import quantity
from aatest.results.rounding import measurement_text
from aatest.station.catalogue import _run_dir_named, present_files

if TYPE_CHECKING:
    from aatest.records.models import CalibrationRecord

#: the longest serial the page looks up (the procedure schema allows 200 characters)
MAX_SERIAL_CHARS = 200


def check_serial(serial: str) -> str:
    """The serial as looked up; empty, over-long or control characters are an InputError."""
    serial = serial.strip()
    if not serial or len(serial) > MAX_SERIAL_CHARS or not serial.isprintable():
        raise InputError("a unit serial is 1–200 printable characters")
    return serial


def unit_history(records_url: str | None, runs_dir: Path, serial: str) -> dict[str, Any]:
    """The page's JSON: the unit's records (oldest first) and the trend of its key quantity."""
    from aatest.records.history import quantity_names
    from aatest.records.store import RecordStore

    serial = check_serial(serial)
    with RecordStore.open(records_url, create=False) as store:
        records = store.history(serial, include_simulations=True)
        where = store.name
    names = quantity_names(records)
    return {"serial": serial, "store": where,
            "records": [_row(r, runs_dir) for r in records],
            "trend": _trend(records, names[0]) if names else None}


def _row(record: CalibrationRecord, runs_dir: Path) -> dict[str, Any]:
    local = _local_run(Path(record.bundle), runs_dir)
    shown = []
    for name, stated in sorted(record.quantities.items()):
        key, _, channel = name.partition(".")
        q = quantity(key)
        shown.append({"name": q.name, "channel": channel,
                      "text": measurement_text(stated.value, stated.expanded_uncertainty, q.unit,
                                                digits=q.digits)})
    return {"certificate_number": record.certificate_number, "procedure": record.procedure,
            "model": record.model, "calibrated_utc": record.calibrated_utc.isoformat(
                timespec="seconds"),
            "overall": record.overall_verdict, "kind": record.kind, "operator": record.operator,
            "signed": record.key_fingerprint is not None, "quantities": shown,
            "run": local.name if local is not None else None,
            "files": present_files(local) if local is not None else []}


def _trend(records: list[CalibrationRecord], name: str) -> dict[str, Any]:
    """One quantity over time: UTC seconds, value and U (None where not stated)."""
    key, _, channel = name.partition(".")
    q = quantity(key)
    rows = [r for r in records if name in r.quantities]
    return {"name": q.name, "channel": channel, "unit": q.unit,
            "t_s": [r.calibrated_utc.timestamp() for r in rows],
            "value": [r.quantities[name].value for r in rows],
            "u": [r.quantities[name].expanded_uncertainty for r in rows]}


def _local_run(bundle: Path, runs_dir: Path) -> Path | None:
    """The run directory under ``runs_dir`` holding ``bundle``, if any (no other path served)."""
    try:
        if bundle.parent.resolve().parent != runs_dir.resolve():
            return None
        return _run_dir_named(runs_dir, bundle.parent.name)
    except (InputError, OSError):
        return None
