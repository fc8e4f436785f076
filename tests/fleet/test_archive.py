"""Reading the fleet from the store on both engines: rigs, kinds, adjustments."""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path

from aatest.fleet.archive import calibrations_of, diagnoses_of, load, rig_label
from aatest.records.models import QuantityRecord, Registration
from aatest.records.store import RecordStore

WHEN = datetime(2026, 3, 1, 9, 0, tzinfo=UTC)


def _registration(serial: str, bundle: str, results: dict, kind: str = "calibration",
                  command: str = "run") -> Registration:
    return Registration(model="sr207", serial=serial, command=command, kind=kind,  # type: ignore[arg-type]
                        procedure="p", lab="L", calibrated_utc=WHEN, bundle=bundle,
                        results=results, quantities={"bias.v_sz": QuantityRecord(
                            value=2.5, expanded_uncertainty=1e-3, unit="V")})


def test_rig_adjustment_and_kind_survive_the_store(store_url: str, tmp_path: Path) -> None:
    adjusted = {"metadata": {"table_serial": "TT-7", "adjustment": {
        "made": True, "as_left": {"bias.v_sz": 2.5001, "note": "not a number"}}}}
    unnamed = {"rig": {"turntable": {"plugin": "acutrol"}, "daq": {"plugin": "ni"},
                       "capabilities": {"turntable": {"rate_dps": 1}}}}
    with RecordStore.open(store_url) as store:
        store.register(_registration("U1", str(tmp_path / "1.html"), adjusted))
        store.register(_registration("U2", str(tmp_path / "2.html"), unnamed))
        store.register(_registration("U3", str(tmp_path / "3.html"), adjusted, "simulation"))
        store.register(_registration("U1", str(tmp_path / "d.json"), adjusted,
                                     command="diagnose"))
        rows = load(store)
        everything = load(store, include_simulations=True)
    assert [f.record.serial for f in calibrations_of(rows)] == ["U1", "U2"]
    assert [f.record.serial for f in diagnoses_of(rows)] == ["U1"]
    assert len(calibrations_of(everything)) == 3
    first, second = calibrations_of(rows)
    assert first.rig == "TT-7" and first.as_left == {"bias.v_sz": 2.5001}
    # no serial reported: the plugins and a hash of the rig description (capabilities aside)
    assert second.rig.startswith("acutrol/ni #") and len(second.rig) == len("acutrol/ni #") + 8
    assert second.rig == rig_label({"rig": {"turntable": {"plugin": "acutrol"},
                                            "daq": {"plugin": "ni"}}})
