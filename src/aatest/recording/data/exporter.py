"""Export a Dataset as a measured-data import directory (docs/interfaces.md §3).

``aatest export RUN_DIR --csv DIR`` writes ``dataset.yaml`` plus ``s<NN>_table.csv`` and
``s<NN>_daq.csv`` per step, so a recording can be analysed by other tools, and so
``aatest analyze DIR`` on the export gives the numbers it gives on the recording.

Columns. Table CSV: the contract's ``time_s, position_deg, rate_dps, accel_dps2, sync_pulse``
(the moving axis: ``outer_*`` for ``axis: outer`` steps, else ``inner_*``), then every other
table channel under its canonical name (``outer_position_deg`` — a contract column —,
``outer_rate_dps``, feedback channels, ``fp_latch_s`` when recorded, ...). DAQ CSV:
``time_s, sync_pulse, trigger``, the sensor voltages, ``temperature_c``, then any other channel.
The importer reads the canonical extra columns back, so nothing an analysis uses is lost; the
recording's analysis list and report template go to dataset.yaml, so ``aatest analyze`` runs
the same analyses on the export.

Precision. Every number is written as the shortest decimal that parses back to the same
binary value (Arrow's CSV writer: at most 17 significant digits for float64, 9 for float32;
whole numbers without a decimal point, e.g. ``2`` and ``1e+17``), so import(export(dataset))
reproduces float64 channels bit-exactly and float32 channels to their own precision (read back
as float64). Lines end in ``\n``; the header is never quoted.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.csv as pa_csv
from pydantic import BaseModel
from ruamel.yaml import YAML

from aatest.engine.errors import InputError
from aatest.engine.logs import SampledLog
from aatest.engine.rig_description import Instruments
from aatest.engine.simulation import SIMULATED_PARTS_KEY, simulated_parts
from aatest.engine.steps import Mounting, PlannedStep
from aatest.recording.data.importer import (
    DAQ_REQUIRED,
    MANIFEST,
    TABLE_REQUIRED,
    RecordedCapabilities,
)
from aatest.recording.dataset import Dataset, StepData

#: threads formatting CSV files (one per file of a step: table and DAQ)
_WRITERS = 2
#: rows Arrow formats per batch (its default, 1024, spends ~10 % more CPU in per-batch work)
_WRITE_BATCH_ROWS = 16384
#: PlannedStep fields written to dataset.yaml when set (extensions the importer accepts)
_STEP_EXTENSIONS = (
    "rate_dps", "amplitude_deg", "cycles", "outer_rate_dps", "temperature_c", "group",
)


def _moving_axis(step: PlannedStep) -> str:
    return "outer" if step.axis == "outer" else "inner"


def _arrow_column(values: np.ndarray) -> pa.Array[Any]:
    """One column for the CSV writer: 0/1 booleans as uint8, everything else as logged."""
    arr = np.asarray(values)
    column: pa.Array[Any] = pa.array(arr.astype(np.uint8) if arr.dtype.kind == "b" else arr)
    return column


def write_csv(path: Path, columns: dict[str, np.ndarray]) -> None:
    """Write named equal-length columns as a header row plus one row per sample.

    The numbers are formatted by Arrow's CSV writer (C++, shortest round-trip decimals), which
    is what makes exporting a long recording take seconds rather than minutes.
    """
    table = pa.table({name: _arrow_column(values) for name, values in columns.items()})
    options = pa_csv.WriteOptions(include_header=False, quoting_style="none",
                                  batch_size=_WRITE_BATCH_ROWS)
    # Arrow's own file: its writes never take the GIL (a Python file object would, once per
    # batch, while the other writer thread and the decoder want it)
    with pa.OSFile(str(path), "wb") as stream:
        stream.write((",".join(columns) + "\n").encode("utf-8"))
        pa_csv.write_csv(table, stream, write_options=options)


def table_columns(
    step: PlannedStep, table: SampledLog, present: Collection[str] | None = None
) -> dict[str, np.ndarray]:
    """Table CSV columns: the contract columns of the moving axis, then the rest by name.

    ``present`` (an imported dataset's real channels) leaves out channels the importer had
    filled in, so a re-import fills them identically and still knows they were absent.
    """
    me = _moving_axis(step)
    moving = {f"{me}_position_deg", f"{me}_rate_dps", f"{me}_accel_dps2", "sync_pulse"}
    columns = {"time_s": table.time_s}
    columns |= {k: table[f"{me}_{k}"] for k in TABLE_REQUIRED[1:4]}
    columns["sync_pulse"] = table["sync_pulse"]
    columns |= {
        k: v for k, v in table.channels.items()
        if k not in moving and (present is None or k in present)
    }
    return columns


def daq_columns(daq: SampledLog, present: Collection[str] | None = None) -> dict[str, np.ndarray]:
    """DAQ CSV columns: time, sync, trigger, sensor volts, temperature, then the rest."""
    columns = {"time_s": daq.time_s}
    columns |= {k: daq[k] for k in DAQ_REQUIRED[1:]}
    columns |= {k: daq[k] for k in daq.sensor_channels()}
    columns |= {
        k: v for k, v in daq.channels.items()
        if k not in columns and (present is None or k in present)
    }
    return columns


def _number(value: float | None) -> float | None:
    return None if value is None else float(value)


def step_entry(step: PlannedStep, table_name: str, daq_name: str) -> dict[str, Any]:
    """The ``steps:`` entry of one step in dataset.yaml."""
    if step.kind not in ("static", "sine", "constant_rate"):
        raise InputError(f"step {step.id!r}: kind {step.kind!r} cannot be exported as CSV")
    entry: dict[str, Any] = {"id": step.id, "kind": step.kind, "axis": step.axis}
    if step.kind == "sine":
        accel = step.accel_dps2
        if accel is None and step.amplitude_deg is not None and step.frequency_hz:
            accel = step.amplitude_deg * (2 * math.pi * step.frequency_hz) ** 2
        entry |= {"frequency_hz": _number(step.frequency_hz), "accel_dps2": _number(accel)}
    elif step.accel_dps2 is not None:
        entry["accel_dps2"] = float(step.accel_dps2)
    entry |= {"inner_deg": float(step.inner_deg), "outer_deg": float(step.outer_deg),
              "table": table_name, "daq": daq_name}
    for key in _STEP_EXTENSIONS:
        value = getattr(step, key)
        if value is not None:
            entry[key] = value if isinstance(value, (str, int)) else float(value)
    if step.repetition != 1:
        entry["repetition"] = step.repetition
    if not step.motor_on:
        entry["motor_on"] = False
    if step.settle_s:
        entry["settle_s"] = float(step.settle_s)
    if step.mounting != Mounting():
        entry["mounting"] = step.mounting.model_dump(mode="json")
    return entry


def manifest(dataset: Dataset, entries: list[dict[str, Any]]) -> dict[str, Any]:
    """The dataset.yaml document."""
    doc: dict[str, Any] = {
        "procedure": dataset.procedure,
        "sample_rate_hz": float(dataset.sample_rate_hz),
    }
    t_ref_c = dataset.metadata.get("t_ref_c")
    if isinstance(t_ref_c, (int, float)):
        doc["t_ref_c"] = float(t_ref_c)
    analysis = dataset.metadata.get("analysis")
    if isinstance(analysis, (list, tuple)) and all(isinstance(a, (str, dict)) for a in analysis):
        doc["analysis"] = list(analysis)
    template = dataset.metadata.get("report_template")
    if isinstance(template, str):
        doc["report_template"] = template
    if parts := simulated_parts(dataset.metadata):  # exported simulations stay simulations
        doc[SIMULATED_PARTS_KEY] = parts
    if (instruments := stated_instruments(dataset)) is not None:
        doc["instruments"] = instruments
    if (capabilities := recorded_capabilities(dataset)) is not None:
        doc["capabilities"] = capabilities
    doc["sensors"] = [s.model_dump(mode="json") for s in dataset.sensors]
    doc["steps"] = entries
    return doc


def stated_instruments(dataset: Dataset) -> dict[str, Any] | None:
    """The rig description's ``instruments`` block recorded with ``dataset``, or None.

    Why: an import reads the stated logger, encoder and thermometer from this block
    (diagnose's converter, the uncertainty budgets); without it an analysis of the export would
    silently fall back to the stated defaults. Only what the rig description states is written
    (``exclude_unset``), as the recording keeps it, so a default stays a default after import.

    Raises
    ------
    InputError
        The recorded block is not a valid ``instruments`` block (it names what is wrong).
    """
    return _recorded_block(dataset, "instruments", Instruments,
                           "the recorded rig description's instruments")


def recorded_capabilities(dataset: Dataset) -> dict[str, Any] | None:
    """What the run's plugins declared (``rig.capabilities``, recorded by the engine), or None.

    Why: the budget takes the encoder's resolution and accuracy from the turntable plugin's
    declaration when the rig description states none; without this block an analysis of the
    export would budget the stated default encoder (and say so) where the run had a declared
    one.

    Raises
    ------
    InputError
        The recorded block is not a valid declaration (it names what is wrong).
    """
    return _recorded_block(dataset, "capabilities", RecordedCapabilities,
                           "the recorded plugin declarations (rig capabilities)")


def _recorded_block(dataset: Dataset, key: str, schema: type[BaseModel],
                    what: str) -> dict[str, Any] | None:
    """``metadata.rig[key]`` validated by ``schema``, only the keys it states; None if absent."""
    rig = dataset.metadata.get("rig")
    block = rig.get(key) if isinstance(rig, Mapping) else None
    if block is None:
        return None
    try:
        recorded = schema.model_validate(block)
    except ValueError as exc:  # pydantic's ValidationError is a ValueError
        raise InputError(f"{dataset.source}: {what} cannot be exported: {exc}") from exc
    return recorded.model_dump(mode="json", exclude_unset=True)


def _export_step(
    number: int, data: StepData, out_dir: Path, present: dict[str, Any] | None,
    pool: ThreadPoolExecutor,
) -> tuple[dict[str, Any], list[Future[None]]]:
    """Decode one step and hand its two CSV files to the writer threads; return its
    dataset.yaml entry and the pending writes."""
    width = max(2, len(str(number)))
    table_name = f"s{number:0{width}d}_table.csv"
    daq_name = f"s{number:0{width}d}_daq.csv"
    present = present or {}
    writes = [
        pool.submit(write_csv, out_dir / table_name,
                    table_columns(data.step, data.table, present.get("table"))),
        pool.submit(write_csv, out_dir / daq_name, daq_columns(data.daq, present.get("daq"))),
    ]
    return step_entry(data.step, table_name, daq_name), writes


def export_csv(dataset: Dataset, out_dir: str | Path) -> Path:
    """Write ``dataset`` as an import directory; return the directory.

    Parameters
    ----------
    dataset
        A recording (or an import) read with :func:`aatest.recording.read_dataset`.
    out_dir
        Target directory, created if needed; existing files of the same names are replaced.
        ``dataset.yaml`` is written last, so an interrupted export is never importable.

    Two writer threads format a step's table and DAQ files (Arrow's C++ writer runs without
    the GIL) while the next step is decoded; at most two steps are in memory at a time.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    present = dataset.metadata.get("columns_present") or {}
    entries = []
    with ThreadPoolExecutor(max_workers=_WRITERS, thread_name_prefix="csv") as pool:
        previous: list[Future[None]] = []
        for i, data in enumerate(dataset.steps, start=1):
            entry, writes = _export_step(i, data, out, present.get(data.step.id), pool)
            entries.append(entry)
            for write in previous:  # bounded: the step before this one is written by now
                write.result()
            previous = writes
        for write in previous:
            write.result()
    yaml = YAML(typ="safe", pure=True)
    yaml.default_flow_style = False
    with open(out / MANIFEST, "w", encoding="utf-8") as stream:
        yaml.dump(manifest(dataset, entries), stream)
    return out
