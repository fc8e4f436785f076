"""The published pivoted-misalignment evaluation (docs/method.md §4.5, docs/interfaces.md §5).

Input: complex fundamentals per set (A..H), experiment (1..6) and sensor (SZ on I, SY on O,
SX on P). Experiments 1/4 excite I, 2/5 excite O, 3/6 excite P (inner at 90°, outer excited).
Each sensor's own x/y axes follow the seat frames of the unit (docs/interfaces.md §4): S_Z x = P,
y = O; S_Y x = I, y = P; S_X x = O, y = I. Per sensor: cross ratios R = |A_x|/|A_z|, |A_y|/|A_z|,
the non-sensitive resultant ΔA = √(A_x² + A_y²) on the complex values (principal root),
δ_e = arcsin(|ΔA|/|A_z|); per scenario δ = (δ_e(original) − δ_e(pivoted))/2 and the corrected
sensitive response A_S = A_z·cos δ.
"""

from __future__ import annotations

import csv
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

from aatest.engine.errors import ImportDataError

SETS = "ABCDEFGH"
ORIGINAL_SETS = "ACEG"
SCENARIOS = {"1": ("A", "B"), "2": ("C", "D"), "3": ("E", "F"), "4": ("G", "H")}
SENSOR_AXIS = {"SZ": "I", "SY": "O", "SX": "P"}
AXIS_SENSOR = {v: k for k, v in SENSOR_AXIS.items()}
#: sensor → table axis of its own x and y (seat frames)
SENSOR_XY = {"SZ": ("P", "O"), "SY": ("I", "P"), "SX": ("O", "I")}
EXPERIMENT_AXIS = {1: "I", 2: "O", 3: "P", 4: "I", 5: "O", 6: "P"}
#: experiments 4–6 are the pivoted mounting (1–3 the original one)
FIRST_PIVOTED_EXPERIMENT = 4
_COLUMNS = ("set", "experiment", "sensor", "re", "im")

Spectra = dict[tuple[str, str, str], complex]  # (set, input axis, sensor) → fundamental


def sensor_set_values(spectra: Spectra, set_name: str, sensor: str) -> dict[str, Any] | None:
    """Cross ratios, ΔA and δ_e of one sensor in one set (None when experiments are missing)."""
    x_axis, y_axis = SENSOR_XY[sensor]
    keys = [(set_name, ax, sensor) for ax in (SENSOR_AXIS[sensor], x_axis, y_axis)]
    if any(k not in spectra for k in keys):
        return None
    a_z, a_x, a_y = (spectra[k] for k in keys)
    delta_a = complex(np.sqrt(complex(a_x**2 + a_y**2)))
    ratio = min(abs(delta_a) / abs(a_z), 1.0)
    return {"cross_ratio_x": abs(a_x) / abs(a_z), "cross_ratio_y": abs(a_y) / abs(a_z),
            "delta_A": [delta_a.real, delta_a.imag],
            "delta_e_deg": float(np.degrees(np.arcsin(ratio))),
            "A_z": [a_z.real, a_z.imag]}


def evaluate(spectra: Spectra) -> dict[str, Any]:
    """The contract §5 document from (set, input axis, sensor) → complex fundamental."""
    sets: dict[str, dict[str, Any]] = {}
    for set_name in SETS:
        row = {sensor: v for sensor in SENSOR_AXIS
               if (v := sensor_set_values(spectra, set_name, sensor)) is not None}
        if row:
            sets[set_name] = row
    scenarios: dict[str, dict[str, Any]] = {}
    for key, (orig, piv) in SCENARIOS.items():
        if orig not in sets or piv not in sets:
            continue
        scen = {}
        for sensor in SENSOR_AXIS:
            if sensor in sets[orig] and sensor in sets[piv]:
                delta = 0.5 * (sets[orig][sensor]["delta_e_deg"] - sets[piv][sensor]["delta_e_deg"])
                a_z = complex(*sets[orig][sensor]["A_z"]) * np.cos(np.radians(delta))
                scen[sensor] = {"delta_deg": delta, "A_S": [a_z.real, a_z.imag]}
        scenarios[key] = scen
    return {"sets": sets, "scenarios": scenarios}


def _parse_row(path: Path, line: int, row: dict[str, str]) -> tuple[tuple[str, str, str], complex]:
    set_name = (row.get("set") or "").strip().upper()
    sensor = (row.get("sensor") or "").strip().upper()
    if set_name not in SETS or len(set_name) != 1:
        raise ImportDataError(path, f"set {row.get('set')!r} is not one of A..H", line)
    if sensor not in SENSOR_AXIS:
        raise ImportDataError(path, f"sensor {row.get('sensor')!r} is not one of SZ, SY, SX", line)
    try:
        experiment = int((row.get("experiment") or "").strip())
        value = complex(float(row["re"]), float(row["im"]))
    except (TypeError, ValueError, KeyError) as exc:
        raise ImportDataError(path, f"experiment/re/im not numeric ({exc})", line) from exc
    if experiment not in EXPERIMENT_AXIS:
        raise ImportDataError(path, f"experiment {experiment} is not 1..6", line)
    # the original-mounting sets A/C/E/G hold only experiments 1–3
    if experiment >= FIRST_PIVOTED_EXPERIMENT and set_name in ORIGINAL_SETS:
        raise ImportDataError(path, f"experiment {experiment} (pivoted) does not belong to the "
                              f"original-mounting set {set_name} (A/C/E/G take 1–3)", line)
    return (set_name, EXPERIMENT_AXIS[experiment], sensor), value


def read_spectra(csv_path: str | Path) -> Spectra:
    """Read ``set, experiment, sensor, re, im`` rows; repeated rows are averaged (complex)."""
    path = Path(csv_path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except OSError as exc:
        raise ImportDataError(path, f"cannot read: {exc.strerror or exc}") from exc
    reader = csv.DictReader(text.splitlines())
    fields = [f.strip().lower() for f in reader.fieldnames or []]
    missing = [c for c in _COLUMNS if c not in fields]
    if missing:
        raise ImportDataError(path, f"missing column(s) {', '.join(missing)}; expected "
                              f"{', '.join(_COLUMNS)}", 1)
    reader.fieldnames = fields
    sums: dict[tuple[str, str, str], list[complex]] = defaultdict(list)
    for line, row in enumerate(reader, start=2):
        key, value = _parse_row(path, line, row)
        sums[key].append(value)
    if not sums:
        raise ImportDataError(path, "no data rows", 2)
    return {k: complex(np.mean(v)) for k, v in sums.items()}


def misalignment_from_spectra(csv_path: str | Path) -> dict[str, Any]:
    """``aatest misalignment SPECTRA.csv --json``: the contract §5 document from a CSV.

    Raises
    ------
    ImportDataError
        With ``file:line`` when a row or the header is malformed.
    """
    return evaluate(read_spectra(csv_path))
