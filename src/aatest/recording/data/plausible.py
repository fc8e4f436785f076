"""Physically possible values of imported measured data, refused at their file and line.

A CSV cell may be a finite float and still no measurement: ``1e300`` V at a sensor's output or
``1e300`` ° of table position is a corrupted file, not a result. Left in, such a value
overflows float64 in the analyses (a second difference multiplies a position by fs² ≈ 4e6, an
RMS squares it) and becomes inf or NaN without saying where it came from. The import refuses
it instead, naming the file, the line and the column (exit 2), like any other malformed cell.
A TDMS or MF4 channel (:mod:`aatest.recording.data.logger_import`) is held to the same ranges
after its mapped scaling, named by file, group, channel and sample index (it has no lines).

Each range is far beyond any instrument aatest characterises — it only separates measurements
from impossible numbers, and keeps every later product (× fs², squares) finite.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from aatest.engine.errors import ImportDataError
from aatest.recording.data.csv_table import CsvColumns

#: |position| (°): 1e9 ° is 2.8 million turns, more than a rate table turning at 10 000 °/s
#: for a whole day (8.6e8 °)
POSITION_LIMIT_DEG = 1e9
#: |rate| (°/s): 1e6 °/s is 167 000 rpm, beyond any rate table or centrifuge
RATE_LIMIT_DPS = 1e6
#: |acceleration| (°/s²): 1e9 °/s² is 1.7e7 rad/s², beyond any angular shock table
ACCEL_LIMIT_DPS2 = 1e9
#: |sensor output| (V): no data-acquisition input carries 1 kV
VOLTAGE_LIMIT_V = 1e3
#: temperatures (°C) a logged sensor can have: above absolute zero, below any chamber's limit
TEMPERATURE_RANGE_C = (-273.15, 1000.0)


def range_of(column: str) -> tuple[float, float, str] | None:
    """The possible ``(low, high, unit)`` of a table column by its name's unit, else None:
    the limits in that unit (°, °/s or °/s²)."""
    for suffix, limit, unit in (("_deg", POSITION_LIMIT_DEG, "°"), ("_dps", RATE_LIMIT_DPS, "°/s"),
                                ("_dps2", ACCEL_LIMIT_DPS2, "°/s²")):
        if column.endswith(suffix):
            return -limit, limit, unit
    return None


def checked(csv: CsvColumns, column: str, low: float, high: float, unit: str) -> np.ndarray:
    """``column`` of ``csv``, refused at its first value outside ``[low, high]`` (file, line,
    column and the range in the message); ``low`` and ``high`` are in the column's ``unit``
    (°, °/s, °/s² or V)."""
    values = csv.columns[column]
    bad = np.flatnonzero(~((values >= low) & (values <= high)))
    if bad.size:
        raise ImportDataError(csv.path, f"{column} {values[bad[0]]:g} {unit} is outside "
                                        f"{low:g}…{high:g} {unit}: not a possible measurement",
                              line=int(csv.row_lines[bad[0]]))
    return values


def check_table(csv: CsvColumns) -> None:
    """Every position, rate and acceleration column of a table file within its range."""
    for column in csv.columns:
        found = range_of(column)
        if found is not None:
            checked(csv, column, *found)


def check_volts(csv: CsvColumns, sensors: list[str]) -> None:
    """Every sensor column of a DAQ file within ±:data:`VOLTAGE_LIMIT_V`."""
    for column in sensors:
        checked(csv, column, -VOLTAGE_LIMIT_V, VOLTAGE_LIMIT_V, "V")


def temperature(csv: CsvColumns) -> np.ndarray:
    """The ``temperature_c`` column within :data:`TEMPERATURE_RANGE_C`."""
    return checked(csv, "temperature_c", *TEMPERATURE_RANGE_C, "°C")


def range_of_channel(name: str, sensors: list[str]) -> tuple[float, float, str] | None:
    """The possible ``(low, high, unit)`` of a canonical channel: a table column's by its unit,
    a sensor's ±:data:`VOLTAGE_LIMIT_V`, ``temperature_c``'s :data:`TEMPERATURE_RANGE_C`;
    None for channels with no physical range here (time, pulses, latches). The limits are in
    the returned unit: °, °/s, °/s², V or °C."""
    if name in sensors:
        return -VOLTAGE_LIMIT_V, VOLTAGE_LIMIT_V, "V"
    if name == "temperature_c":
        return *TEMPERATURE_RANGE_C, "°C"
    return range_of(name)


def check_samples(path: str | Path, where: str, name: str, values: np.ndarray, start: int,
                  sensors: list[str]) -> None:
    """Refuse the first sample of a logger channel (canonical ``name``, in aatest's unit)
    outside its range, naming ``path``, ``where`` (group and channel) and its sample index
    counted from the record's start (``values`` begin at sample ``start``)."""
    found = range_of_channel(name, sensors)
    if found is None:
        return
    low, high, unit = found
    bad = np.flatnonzero(~((values >= low) & (values <= high)))
    if bad.size:
        raise ImportDataError(path, f"{where}: {name} {values[bad[0]]:g} {unit} at sample "
                                    f"{start + int(bad[0])} is outside {low:g}…{high:g} {unit}: "
                                    "not a possible measurement")
