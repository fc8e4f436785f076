"""Export a Dataset as a logger file (NI TDMS or ASAM MF4) with its ``mapping.yaml``.

``aatest export RUN_DIR --tdms DIR`` (or ``--mf4 DIR``) writes ``DIR/recording.tdms`` (or
``recording.mf4``) and ``DIR/mapping.yaml``; ``aatest analyze DIR`` reads them back through
:mod:`aatest.recording.data.logger_import`. Each step becomes two groups, ``s<NN>_table`` and
``s<NN>_daq``, whose channels carry the CSV export's column names
(:func:`aatest.recording.data.exporter.table_columns`, ``daq_columns``) and their units as the
file's own unit property, so the files also read naturally in NI's and ASAM tools.

Streaming. A step is written piece by piece as the recording decodes it
(:meth:`~aatest.recording.dataset.LazySteps.pieces`: 60 s blocks of a streamed DAQ record): a TDMS
segment per piece, an MF4 group extended per piece (asammdf keeps the samples in its temporary
file until ``save``), so memory holds one piece, never a step or the run.

Time. TDMS stores the time stamps as a float64 channel ``time_s`` (a waveform's start and
increment could not reproduce a logger's own clock bit for bit); MF4 as each group's float64
master channel. Numbers are stored as logged (float64, 0/1 lines as uint8), so
import(export(dataset)) reproduces the channels bit-exactly.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from ruamel.yaml import YAML

from aatest.engine.logs import DAQ_AUX_CHANNELS, TABLE, TABLE_CHANNELS, SampledLog
from aatest.recording.data.exporter import daq_columns, manifest, step_entry, table_columns
from aatest.recording.data.mapping import MAPPING
from aatest.recording.dataset import Dataset, LazySteps

#: the canonical units' spelling in the mapping (``TABLE_CHANNELS`` writes ``deg/s^2``)
_PULSES = ("sync_pulse", "trigger")
_MOTION = {"position_deg": ("position", "deg"), "rate_dps": ("rate", "deg/s"),
           "accel_dps2": ("accel", "deg/s^2")}


def _pieces(dataset: Dataset, index: int, source: str) -> Iterator[SampledLog]:
    """The step's log in consecutive pieces (the whole log when the data has no pieces)."""
    if isinstance(dataset.steps, LazySteps):
        yield from dataset.steps.pieces(index, source)
    else:
        step = dataset.steps[index]
        yield step.table if source == TABLE else step.daq


def _stored(values: np.ndarray) -> np.ndarray:
    """A channel as the file stores it: 0/1 booleans as uint8, numbers as logged."""
    arr = np.ascontiguousarray(values)
    return arr.astype(np.uint8) if arr.dtype.kind == "b" else arr


def _unit(name: str, sensors: set[str]) -> str:
    if name in sensors:
        return "V"
    if name == "time_s":
        return "s"
    motion = _MOTION.get(name)
    if motion is not None:
        return motion[1]
    return {**TABLE_CHANNELS, **DAQ_AUX_CHANNELS}.get(name, "")


class _StepColumns:
    """The columns of each piece of a step, and every column name any step had."""

    def __init__(self, dataset: Dataset) -> None:
        self.dataset = dataset
        self.present = dataset.metadata.get("columns_present") or {}
        self.sensors = {s.channel for s in dataset.sensors}
        self.names: dict[str, set[str]] = {"table": set(), "daq": set()}

    def __call__(self, index: int, source: str) -> Iterator[dict[str, np.ndarray]]:
        step = self.dataset.planned[index]
        present = (self.present.get(step.id) or {}).get(source)
        for piece in _pieces(self.dataset, index, source):
            columns = (table_columns(step, piece, present) if source == TABLE
                       else daq_columns(piece, present))
            self.names[source] |= set(columns)
            yield {name: _stored(values) for name, values in columns.items()}


def _group_names(number: int, count: int) -> tuple[str, str]:
    width = max(2, len(str(count)))
    return f"s{number:0{width}d}_table", f"s{number:0{width}d}_daq"


def export_tdms(dataset: Dataset, out_dir: str | Path) -> Path:
    """Write ``dataset`` as ``recording.tdms`` plus ``mapping.yaml``; return the directory."""
    from nptdms import ChannelObject, GroupObject, TdmsWriter

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    columns = _StepColumns(dataset)
    entries = []
    with TdmsWriter(str(out / "recording.tdms")) as writer:
        for i, step in enumerate(dataset.planned):
            groups = _group_names(i + 1, len(dataset.planned))
            for source, group in zip(("table", "daq"), groups, strict=True):
                for k, piece in enumerate(columns(i, source)):
                    objects: list[Any] = [GroupObject(group, properties={"step": step.id})]
                    objects += [ChannelObject(group, name, values, properties=(
                        {} if k else {"unit_string": _unit(name, columns.sensors)}))
                        for name, values in piece.items()]
                    writer.write_segment(objects)
            entries.append(step_entry(step, *groups))
    return _write_mapping(dataset, out, "tdms", "recording.tdms", entries, columns.names)


def export_mf4(dataset: Dataset, out_dir: str | Path) -> Path:
    """Write ``dataset`` as ``recording.mf4`` plus ``mapping.yaml``; return the directory."""
    from asammdf import MDF, Signal

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    columns = _StepColumns(dataset)
    entries = []
    mdf = MDF(version="4.10")
    try:
        for i, step in enumerate(dataset.planned):
            groups = _group_names(i + 1, len(dataset.planned))
            for source, group in zip(("table", "daq"), groups, strict=True):
                index = len(mdf.groups)
                for k, piece in enumerate(columns(i, source)):
                    time_s = piece.pop("time_s")
                    if k == 0:
                        mdf.append([Signal(values, time_s, name=name,
                                           unit=_unit(name, columns.sensors))
                                    for name, values in piece.items()],
                                   acq_name=group, comment=f"step {step.id}")
                    else:
                        mdf.extend(index, [(time_s, None), *((v, None) for v in piece.values())])
            entries.append(step_entry(step, *groups))
        mdf.save(str(out / "recording.mf4"), overwrite=True)
    finally:
        mdf.close()
    return _write_mapping(dataset, out, "mf4", "recording.mf4", entries, columns.names)


def _channel(name: str, sensors: set[str], required: bool = True) -> dict[str, Any]:
    entry: dict[str, Any] = {"channel": name}
    unit = _unit(name, sensors)
    if name not in _PULSES and unit:
        entry["unit"] = unit
    if not required:
        entry["required"] = False
    return entry


def mapping_document(dataset: Dataset, kind: str, file_name: str,
                     entries: list[dict[str, Any]], names: dict[str, set[str]]
                     ) -> dict[str, Any]:
    """The mapping.yaml document of an export: the dataset.yaml keys plus the mapping."""
    sensors = {s.channel for s in dataset.sensors}
    table: dict[str, Any] = {key: _channel(name, sensors) for name, (key, _) in _MOTION.items()}
    table["freeze_pulse"] = _channel("sync_pulse", sensors)
    if "fp_latch_s" in names["table"]:
        table["fp_latch_s"] = _channel("fp_latch_s", sensors, required=False)
    extras = [n for n in TABLE_CHANNELS if n in names["table"]
              and n not in ("sync_pulse", "fp_latch_s")]
    if extras:
        table["channels"] = {n: _channel(n, sensors, required=False) for n in extras}
    daq: dict[str, Any] = {"freeze_pulse": _channel("sync_pulse", sensors),
                           "trigger": _channel("trigger", sensors),
                           "sensors": {s: _channel(s, sensors) for s in sorted(sensors)}}
    if "temperature_c" in names["daq"]:
        daq["temperature"] = _channel("temperature_c", sensors, required=False)
    if kind == "tdms":
        table["time"], daq["time"] = _channel("time_s", sensors), _channel("time_s", sensors)
    doc = manifest(dataset, entries)
    return {"format": kind, "file": file_name, **doc, "table": table, "daq": daq}


def _write_mapping(dataset: Dataset, out: Path, kind: str, file_name: str,
                   entries: list[dict[str, Any]], names: dict[str, set[str]]) -> Path:
    """Write mapping.yaml last, so an interrupted export is never importable."""
    yaml = YAML(typ="safe", pure=True)
    yaml.default_flow_style = False
    with open(out / MAPPING, "w", encoding="utf-8") as stream:
        yaml.dump(mapping_document(dataset, kind, file_name, entries, names), stream)
    return out
