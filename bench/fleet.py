"""Benchmark: the fleet views over a growing archive; prints records per second and the
scaling ratio (time for 4N records over 4 × the time for N: 1.0 is linear).

The archive is synthetic (registrations of calibrations and JSON diagnoses across units, rigs
and dates, as ``tests/fleet/fleet_archive.py`` builds them, without running the twin), in a
SQLite file under a temporary directory.

    python bench/fleet.py [--units 100] [--calibrations 5]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np

from aatest.fleet.analysis import fleet_charts, fleet_diagnoses, unit_intervals
from aatest.fleet.archive import load
from aatest.fleet.recurrence import summarise
from aatest.records.models import QuantityRecord, Registration
from aatest.records.store import RecordStore

T0 = datetime(2020, 1, 1, tzinfo=UTC)
RIGS = ("TT-1", "TT-2", "TT-3")
NOMINAL, U = 0.004014, 2e-6


def _registration(folder: Path, serial: str, rig: str, i: int, value: float | None,
                  command: str = "run") -> Registration:
    bundle = folder / f"{serial}-{i}-{command}" / ("diagnosis.json" if value is None
                                                   else "report.html")
    if value is None:
        bundle.parent.mkdir(parents=True)
        bundle.write_text(json.dumps({"findings": [{"effect": "rate_ripple"}]
                                      if rig == "TT-1" else []}))
    quantities = {} if value is None else {"scale_factor.v_sz": QuantityRecord(
        value=value, expanded_uncertainty=U, unit="V/(°/s²)")}
    results = {"procedure": "scale-factor", "metadata": {"table_serial": rig, "sensors": [
        {"channel": "v_sz", "nominal_scale_v_per_dps2": NOMINAL}]}}
    offset_days = int(serial[1:]) % 30  # units of one batch come back on different days
    return Registration(model="sr207", serial=serial, command=command, procedure="scale-factor",
                        lab="Bench", calibrated_utc=T0 + timedelta(days=180 * i + offset_days),
                        bundle=str(bundle), results=results, quantities=quantities)


def build(folder: Path, units: int, calibrations: int) -> str:
    url = f"sqlite:///{folder / 'records.sqlite'}"
    rng = np.random.default_rng(1)
    with RecordStore.open(url) as store:
        for u in range(units):
            serial, rig = f"U{u:05d}", RIGS[u % len(RIGS)]
            for i in range(calibrations):
                drift = 1e-6 * i
                store.register(_registration(folder, serial, rig, i,
                                             NOMINAL + drift + float(rng.normal(0, U / 4))))
            store.register(_registration(folder, serial, rig, calibrations, None, "diagnose"))
    return url


def views(url: str, serial: str) -> float:
    start = time.perf_counter()
    with RecordStore.open(url, create=False) as store:
        rows = load(store)
    fleet_charts(rows)
    summarise(fleet_diagnoses(rows, None))
    unit_intervals([f for f in rows if f.record.serial == serial],
                   {"scale_factor.v_sz": (NOMINAL * 0.99, NOMINAL * 1.01)}, 0.95)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--units", type=int, default=100)
    parser.add_argument("--calibrations", type=int, default=5)
    args = parser.parse_args()
    seconds = {}
    for scale in (1, 4):
        with tempfile.TemporaryDirectory() as tmp:
            units = args.units * scale
            url = build(Path(tmp), units, args.calibrations)
            seconds[scale] = views(url, "U00000")
            records = units * (args.calibrations + 1)
            print(f"{records} records: views in {seconds[scale]:.2f} s "
                  f"({records / seconds[scale]:.0f} records/s)")
    print(f"scaling ratio (4N over 4 × N): {seconds[4] / (4 * seconds[1]):.2f}")


if __name__ == "__main__":
    main()
