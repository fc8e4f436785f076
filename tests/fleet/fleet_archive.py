"""A records store seeded with synthetic records whose truth the fleet tests know.

* unit ``A1`` (model sr300, rig TT-100): five calibrations half a year apart, the scale factor
  drifting +0.2 % of nominal per year from nominal, U = 2e-6 V/(°/s²); one simulation of it far
  off (must be left out);
* sixteen units ``C01…C16`` calibrated once each on TT-100, scale factors scattered by 2e-6
  about nominal, ``C09`` six sigmas high (the injected out-of-control point);
* diagnoses (JSON bundles with findings): on TT-100 ``R1``, ``R2``, ``R3`` show
  ``rate_ripple`` (the rig's effect) and ``R2`` also ``nonlinearity_cubic`` (one unit's); on
  TT-200 ``B1`` shows ``misalignment`` and ``B2`` nothing; simulated diagnoses of ``B1`` and
  ``B2`` both show ``g_sensitivity`` (a rig effect only if simulations are included).
"""

from __future__ import annotations

import json
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import numpy as np

from aatest.records.models import QuantityRecord, Registration
from aatest.records.store import RecordStore

NOMINAL = 0.004014
TOLERANCE_PCT = 1.0
DRIFT_PER_YEAR = 0.002  # of nominal
U_SCALE = 2e-6
T0 = datetime(2024, 1, 15, 9, 0, tzinfo=UTC)
HALF_YEAR = timedelta(days=182.625)
RIG_EFFECT, UNIT_EFFECT, SIM_EFFECT = "rate_ripple", "nonlinearity_cubic", "g_sensitivity"
OUTLIER = "C09"
#: the drifting unit is of its own model, so the sixteen units alone make the sr207 chart
DRIFTING_MODEL = "sr300"


def _results(rig: str) -> dict[str, Any]:
    return {"procedure": "scale-factor", "metadata": {"table_serial": rig, "sensors": [
        {"channel": "v_sz", "nominal_scale_v_per_dps2": NOMINAL,
         "scale_tolerance_pct": TOLERANCE_PCT}]}}


def _registration(serial: str, rig: str, when: datetime, bundle: Path, value: float | None,
                  command: str = "run", kind: str = "calibration",
                  model: str = "sr207") -> Registration:
    quantities = {} if value is None else {"scale_factor.v_sz": QuantityRecord(
        value=value, expanded_uncertainty=U_SCALE, unit="V/(°/s²)")}
    return Registration(model=model, serial=serial, command=command, kind=kind,  # type: ignore[arg-type]
                        procedure="scale-factor", lab="Test Lab", calibrated_utc=when,
                        bundle=str(bundle), overall_verdict="pass", results=_results(rig),
                        quantities=quantities)


def _diagnosis(folder: Path, serial: str, rig: str, effects: list[str],
               kind: str = "calibration") -> Registration:
    bundle = folder / f"diagnosis-{serial}-{rig}-{kind}" / "diagnosis.json"
    bundle.parent.mkdir(parents=True)
    bundle.write_text(json.dumps({"findings": [
        {"effect": e, "channel": "v_sz", "attributed_to": "table"} for e in effects]}))
    return _registration(serial, rig, T0 + timedelta(days=800), bundle, None, "diagnose", kind)


def drifting_value(when: datetime) -> float:
    years = (when - T0).total_seconds() / (365.25 * 86400)
    return NOMINAL * (1 + DRIFT_PER_YEAR * years)


def seed(url: str, folder: Path) -> None:
    rng = np.random.default_rng(20261126)
    regs = []
    for i in range(5):
        when = T0 + i * HALF_YEAR
        noise = float(rng.normal(0.0, U_SCALE / 4))
        regs.append(_registration("A1", "TT-100", when, folder / f"A1-{i}" / "report.html",
                                  drifting_value(when) + noise, model=DRIFTING_MODEL))
    regs.append(_registration("A1", "TT-100", T0 + 5 * HALF_YEAR, folder / "A1-sim" /
                              "report.html", NOMINAL * 1.5, kind="simulation",
                              model=DRIFTING_MODEL))
    values = rng.normal(NOMINAL, U_SCALE, 16)
    for i, value in enumerate(values, start=1):
        serial = f"C{i:02d}"
        bump = 6 * U_SCALE if serial == OUTLIER else 0.0
        regs.append(_registration(serial, "TT-100", T0 + timedelta(days=10 * i),
                                  folder / serial / "report.html", float(value) + bump))
    regs += [_diagnosis(folder, "R1", "TT-100", [RIG_EFFECT]),
             _diagnosis(folder, "R2", "TT-100", [RIG_EFFECT, UNIT_EFFECT]),
             _diagnosis(folder, "R3", "TT-100", [RIG_EFFECT]),
             _diagnosis(folder, "B1", "TT-200", ["misalignment"]),
             _diagnosis(folder, "B2", "TT-200", []),
             _diagnosis(folder, "B1", "TT-200", [SIM_EFFECT], "simulation"),
             _diagnosis(folder, "B2", "TT-200", [SIM_EFFECT], "simulation")]
    with RecordStore.open(url) as store:
        for r in regs:
            store.register(r)
