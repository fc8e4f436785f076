"""Logger files written by the libraries' own writers (npTDMS, asammdf), not by aatest.

They stand in for what a lab's logger hands over: channel names of the lab's own choosing,
units other than aatest's (radians, millivolts, kelvin), a freeze-pulse line logged as volts,
MF4 groups without names. The numbers come from a twin run's recording.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from asammdf import MDF, Signal
from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter
from ruamel.yaml import YAML
from tolerances import leaves

from aatest.recording.dataset import Dataset

#: how the lab's TDMS logger names and scales the table channels: canonical → (name, unit, k)
TDMS_TABLE = {
    "time_s": ("Time", "s", 1.0),
    "inner_position_deg": ("Position", "rad", math.pi / 180),
    "inner_rate_dps": ("Rate", "deg/s", 1.0),
    "inner_accel_dps2": ("Acceleration", "rad/s^2", math.pi / 180),
    "outer_position_deg": ("OuterPosition", "deg", 1.0),
    "outer_rate_dps": ("OuterRate", "deg/s", 1.0),
    "outer_accel_dps2": ("OuterAcceleration", "deg/s^2", 1.0),
    "inner_feedback_deg": ("InnerEncoder", "deg", 1.0),
    "outer_feedback_deg": ("OuterEncoder", "deg", 1.0),
    "fp_latch_s": ("FPLatch", "s", 1.0),
}
#: the freeze pulse as the DAQ logs it: a 0/5 V line
PULSE_HIGH_V = 5.0


def _table_map(names: dict[str, tuple[str, str, float]]) -> dict[str, Any]:
    def entry(canonical: str) -> dict[str, Any]:
        name, unit, _ = names[canonical]
        return {"channel": name, "unit": unit}

    return {
        "time": entry("time_s"),
        "position": entry("inner_position_deg"), "rate": entry("inner_rate_dps"),
        "accel": entry("inner_accel_dps2"),
        "freeze_pulse": {"channel": "FreezePulse"},
        "fp_latch_s": entry("fp_latch_s"),
        "channels": {k: entry(k) for k in ("outer_position_deg", "outer_rate_dps",
                                           "outer_accel_dps2", "inner_feedback_deg",
                                           "outer_feedback_deg")},
    }


def mapping_yaml(manifest: dict[str, Any], fmt: str, table: dict[str, Any],
                 daq: dict[str, Any], groups: list[tuple[Any, Any]],
                 files: list[str] | None = None, file: str | None = None) -> str:
    """A mapping file: the CSV export's dataset.yaml with groups instead of CSV files."""
    steps = []
    for i, (step, (table_group, daq_group)) in enumerate(
            zip(manifest["steps"], groups, strict=True)):
        entry = dict(step) | {"table": table_group, "daq": daq_group}
        if files is not None:
            entry["file"] = files[i]
        steps.append(entry)
    doc = {"format": fmt} | ({"file": file} if file else {}) | {
        k: v for k, v in manifest.items() if k != "steps"} | {
        "table": table, "daq": daq, "steps": steps}
    yaml = YAML(typ="safe", pure=True)
    yaml.default_flow_style = False
    from io import StringIO

    text = StringIO()
    yaml.dump(doc, text)
    return text.getvalue()


def write_tdms(dataset: Dataset, manifest: dict[str, Any], out: Path) -> Path:
    """``out/logger.tdms`` by npTDMS's TdmsWriter: one group per logger and step, each step in
    two segments (as a logger appends), plus ``out/mapping.yaml``."""
    out.mkdir(parents=True, exist_ok=True)
    groups = []
    with TdmsWriter(str(out / "logger.tdms")) as writer:
        writer.write_segment([RootObject(properties={"author": "test lab"})])
        for i, step in enumerate(dataset.steps):
            table_group, daq_group = f"Step {i + 1} Table", f"Step {i + 1} DAQ"
            groups.append((table_group, daq_group))
            table, daq = step.table, step.daq
            half = len(table) // 2
            for part in (slice(0, half), slice(half, None)):
                objects = [GroupObject(table_group)]
                for canonical, (name, unit, k) in TDMS_TABLE.items():
                    values = table.time_s if canonical == "time_s" else table[canonical]
                    objects.append(ChannelObject(table_group, name, values[part] * k,
                                                 properties={"unit_string": unit}))
                objects.append(ChannelObject(table_group, "FreezePulse",
                                             table["sync_pulse"][part].astype(np.uint8)))
                writer.write_segment(objects)
            writer.write_segment([
                GroupObject(daq_group),
                ChannelObject(daq_group, "Time", daq.time_s, properties={"unit_string": "s"}),
                ChannelObject(daq_group, "Sync", daq["sync_pulse"] * PULSE_HIGH_V,
                              properties={"unit_string": "V"}),
                ChannelObject(daq_group, "Trigger", daq["trigger"].astype(np.int32)),
                ChannelObject(daq_group, "AI0", daq["v_sz"] * 1000.0,
                              properties={"unit_string": "mV"}),
                ChannelObject(daq_group, "Temperature", daq["temperature_c"] + 273.15,
                              properties={"unit_string": "K"}),
            ])
    daq_map = {"time": {"channel": "Time", "unit": "s"},
               "freeze_pulse": {"channel": "Sync", "threshold": PULSE_HIGH_V / 2},
               "trigger": {"channel": "Trigger"},
               "temperature": {"channel": "Temperature", "unit": "K"},
               "sensors": {"v_sz": {"channel": "AI0", "unit": "mV"}}}
    text = mapping_yaml(manifest, "tdms", _table_map(TDMS_TABLE), daq_map, groups,
                        file="logger.tdms")
    (out / "mapping.yaml").write_text(text, encoding="utf-8")
    return out / "mapping.yaml"


def write_mf4(dataset: Dataset, manifest: dict[str, Any], out: Path,
              acq_name: str | None = None) -> Path:
    """One MF4 file per step by asammdf (``MDF.append``/``extend``/``save``): groups without
    acquisition names (found by index; ``acq_name``: both groups named so), time as each
    group's master channel, the sensor as millivolts around its 2.5 V bias (``offset`` in the
    mapping)."""
    out.mkdir(parents=True, exist_ok=True)
    files = []
    names = {k: v for k, v in TDMS_TABLE.items() if k != "time_s"}
    for i, step in enumerate(dataset.steps):
        table, daq = step.table, step.daq
        mdf = MDF(version="4.10")
        half = len(table) // 2
        first = [Signal(table[k][:half] * scale, table.time_s[:half], name=name, unit=unit)
                 for k, (name, unit, scale) in names.items()]
        first.append(Signal(table["sync_pulse"][:half].astype(np.uint8), table.time_s[:half],
                            name="FreezePulse"))
        mdf.append(first, acq_name=acq_name)
        mdf.extend(0, [(table.time_s[half:], None),
                       *((table[k][half:] * scale, None) for k, (_, _, scale) in names.items()),
                       (table["sync_pulse"][half:].astype(np.uint8), None)])
        mdf.append([Signal(daq["sync_pulse"].astype(np.uint8), daq.time_s, name="Sync"),
                    Signal(daq["trigger"].astype(np.uint8), daq.time_s, name="Trigger"),
                    Signal((daq["v_sz"] - 2.5) * 1000.0, daq.time_s, name="AI0", unit="mV"),
                    Signal(daq["temperature_c"], daq.time_s, name="Temp", unit="°C")],
                   acq_name=acq_name)
        name = f"step{i + 1}.mf4"
        mdf.save(str(out / name), overwrite=True)
        mdf.close()
        files.append(name)
    table_map = _table_map(TDMS_TABLE)
    del table_map["time"]  # the master channel
    daq_map = {"freeze_pulse": {"channel": "Sync"}, "trigger": {"channel": "Trigger"},
               "temperature": {"channel": "Temp", "unit": "degC"},
               "sensors": {"v_sz": {"channel": "AI0", "unit": "mV", "offset": 2500.0}}}
    text = mapping_yaml(manifest, "mf4", table_map, daq_map, [(0, 1)] * len(files), files)
    (out / "mapping.yaml").write_text(text, encoding="utf-8")
    return out / "mapping.yaml"


def assert_close_tree(expected: Any, got: Any, rtol: float, atol: float) -> int:
    """Same keys and strings, floats within ``rtol``/``atol``; returns the leaves compared."""
    want, have = dict(leaves(expected)), dict(leaves(got))
    assert set(have) == set(want)
    for key, value in want.items():
        if isinstance(value, float) and isinstance(have[key], (int, float)):
            assert math.isclose(have[key], value, rel_tol=rtol, abs_tol=atol), (
                f"{key}: {have[key]!r} != {value!r}")
        else:
            assert have[key] == value, key
    return len(want)
