"""Measured-data import (docs/interfaces.md §3): a directory with ``dataset.yaml`` and CSV pairs.

Data recorded by other systems becomes the same :class:`~aatest.recording.dataset.Dataset` an
aatest recording gives, so every analysis and ``diagnose`` runs on it unchanged.

``dataset.yaml`` is strict (unknown keys are errors, reported as ``FILE:LINE:COLUMN``); the
CSV files are tolerant (extra columns, any order, whitespace, CRLF) but malformed content is an
:class:`~aatest.engine.errors.ImportDataError` with file and line (see
:mod:`aatest.recording.data.csv_table`). Besides the contract keys, the manifest accepts a few
*extensions*: top-level ``procedure`` (name), ``t_ref_c`` and ``model`` (a sensor-model YAML
whose ``t_ref_c`` sets the temperature reference, default 25 °C), ``analysis`` (the analyses
``aatest analyze`` runs, as in a procedure) and ``report_template``; per step ``amplitude_deg``,
``cycles``, ``rate_dps``, ``outer_rate_dps``, ``temperature_c``, ``group``, ``repetition``,
``motor_on``, ``settle_s``, ``mounting``; per sensor every
:class:`~aatest.engine.datasheet.SensorInfo` field (the contract keys ``channel``, ``axis``,
``nominal_bias_v``, ``nominal_scale_v_per_dps2``, ``range_dps2`` among them).

Channel mapping. The table CSV's ``position_deg, rate_dps, accel_dps2`` are the moving axis
(``outer_*`` for ``axis: outer``, else ``inner_*``). Any column named like a canonical table
channel (``outer_position_deg``, ``inner_rate_dps``, ``outer_feedback_deg``, ...) is taken
as that channel. Channels the file lacks are filled with what the step states: the resting
axis at its ``inner_deg``/``outer_deg`` with zero rate and acceleration, feedback equal to the
position estimate. ``fp_latch_s`` exists only when the file has it (without it the sync pulse
aligns the loggers to one sample only). A DAQ file without ``temperature_c`` gets the step's
``temperature_c`` or ``t_ref_c``. ``Dataset.metadata["columns_present"]`` lists, per step, the
channels that really came from the files.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from aatest.engine.capabilities import TableCapabilities
from aatest.engine.errors import ImportDataError, Problem, ProblemsError
from aatest.engine.logs import DAQ, TABLE, TABLE_CHANNELS, SampledLog
from aatest.engine.rig_description import Instruments
from aatest.engine.steps import Mounting, PlannedStep
from aatest.numerics import TINY
from aatest.positioned_yaml import locate, parse_yaml, read_text, validate_tree
from aatest.recording.data import plausible
from aatest.recording.data.csv_table import CsvColumns, read_csv
from aatest.recording.dataset import Dataset, SensorInfo, StepData

#: manifest fields an import keeps in its metadata as stated: the analyses and report asked
#: for, and the simulated parts (an exported simulation stays a simulation in every format)
STATED_KEYS = frozenset({"analysis", "report_template", "simulated_parts"})


MANIFEST = "dataset.yaml"
IMPORT_FORMAT = "aatest.import/v1"
DEFAULT_T_REF_C = 25.0
TABLE_REQUIRED = ("time_s", "position_deg", "rate_dps", "accel_dps2", "sync_pulse")
DAQ_REQUIRED = ("time_s", "sync_pulse", "trigger")
_MOTION = ("position_deg", "rate_dps", "accel_dps2")
#: threads parsing CSV files (Arrow's single-threaded parser each; see ``_read_files``)
_READERS = 2


class DatasetFileError(ImportDataError, ProblemsError):
    """``dataset.yaml`` is malformed; every problem is located as FILE:LINE:COLUMN."""

    def __init__(self, problems: list[Problem]) -> None:
        self.problems = list(problems)
        self.path = problems[0].file
        self.line = problems[0].line
        Exception.__init__(self, "\n".join(str(p) for p in self.problems))


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class SensorEntry(SensorInfo):
    """One sensor channel of the DAQ files: the engine's sensor record, keys and defaults alike.

    The only import-side rule is that a channel may not be named like a DAQ column of its own.
    """

    @field_validator("channel")
    @classmethod
    def _not_reserved(cls, channel: str) -> str:
        if channel in (*DAQ_REQUIRED, "temperature_c"):
            raise ValueError(f"{channel!r} is a DAQ column of its own, not a sensor channel")
        return channel


class StepEntry(_Strict):
    """One step: what was commanded, and its two CSV files."""

    id: str = Field(min_length=1)
    kind: Literal["static", "sine", "constant_rate"]
    axis: Literal["inner", "outer", "both", "none"] = "inner"
    frequency_hz: float | None = Field(None, gt=0)
    accel_dps2: float | None = None
    rate_dps: float | None = None
    inner_deg: float = 0.0
    outer_deg: float = 0.0
    table: str = Field(min_length=1)
    daq: str = Field(min_length=1)
    amplitude_deg: float | None = None
    cycles: int | None = Field(None, ge=1)
    outer_rate_dps: float | None = None
    temperature_c: float | None = None
    group: str | None = None
    repetition: int = Field(1, ge=1)
    motor_on: bool = True
    settle_s: float = Field(0.0, ge=0)
    mounting: Mounting = Mounting()

    @model_validator(mode="after")
    def _commanded(self) -> StepEntry:
        if self.kind == "sine" and (self.frequency_hz is None or self.accel_dps2 is None):
            raise ValueError("a sine step needs frequency_hz and accel_dps2")
        if self.kind == "constant_rate" and self.rate_dps is None:
            raise ValueError("a constant_rate step needs rate_dps")
        return self


class TurntableDeclaration(_Strict):
    """What the turntable plugin of the exported run declared (``rig.capabilities.turntable``).

    Why: the budget takes the encoder's numbers from the plugin's declaration where the rig
    description states none; an export that dropped it would make the re-imported run's
    budget fall back to the stated defaults.
    """

    plugin: str | None = None
    distribution: str | None = None
    declared: TableCapabilities | None = None


class RecordedCapabilities(_Strict):
    """The declarations the engine recorded beside the rig description (``rig.capabilities``)."""

    turntable: TurntableDeclaration | None = None


class DatasetManifest(_Strict):
    """The ``dataset.yaml`` of an import directory."""

    sensors: list[SensorEntry] = Field(min_length=1)
    sample_rate_hz: float = Field(gt=0)
    steps: list[StepEntry] = Field(min_length=1)
    procedure: str = "imported"
    t_ref_c: float | None = None
    model: str | None = None
    #: analysis names or ``{name: {options}}`` entries, as in a procedure
    analysis: list[str | dict[str, dict[str, Any]]] | None = None
    report_template: str | None = None
    #: the simulated rig parts the data came from (``aatest export`` of a simulation writes
    #: them): imported, the data stay a simulation, never a calibration
    simulated_parts: list[str] | None = None
    #: stated accuracies of the instruments (the logger's above all); absent: stated defaults
    instruments: Instruments | None = None
    #: what the run's plugins declared (``aatest export`` writes it); absent: nothing declared
    capabilities: RecordedCapabilities | None = None

    @model_validator(mode="after")
    def _unique(self) -> DatasetManifest:
        for what, names in (("step id", [s.id for s in self.steps]),
                            ("sensor channel", [s.channel for s in self.sensors])):
            dupes = sorted({n for n in names if names.count(n) > 1})
            if dupes:
                raise ValueError(f"duplicate {what}(s): {', '.join(dupes)}")
        return self


def load_manifest(path: Path) -> tuple[DatasetManifest, Any]:
    """Parse and validate ``dataset.yaml``; return the model and the positioned YAML tree."""
    try:
        tree, data = parse_yaml(read_text(path), str(path))
        return validate_tree(DatasetManifest, tree, data, str(path)), tree
    except ProblemsError as exc:
        raise DatasetFileError(exc.problems) from exc


def _frequency_problem(entry: StepEntry, nyquist_hz: float) -> str | None:
    """Why a step's ``frequency_hz`` cannot be analysed (None when it can)."""
    f_hz = entry.frequency_hz
    if f_hz is None:
        return None
    if f_hz >= nyquist_hz:
        return f"{f_hz:g} Hz is not below the Nyquist frequency {nyquist_hz:g} Hz"
    if entry.kind == "sine" and entry.amplitude_deg is None and entry.accel_dps2 is not None:
        amplitude_deg = entry.accel_dps2 / max((2 * math.pi * f_hz) ** 2, TINY)
        if not math.isfinite(amplitude_deg) or (2 * math.pi * f_hz) ** 2 == 0:
            return (f"{f_hz:g} Hz gives no finite amplitude accel_dps2/(2πf)² "
                    f"for accel_dps2 {entry.accel_dps2:g}")
    return None


def _check_frequencies(manifest: DatasetManifest, tree: Any, manifest_path: Path) -> None:
    """Every sine frequency below the Nyquist frequency of ``sample_rate_hz`` (located).

    A frequency the samples cannot represent (``frequency_hz: 1e+308``) has no cycle to
    analyse; it is an input error at its line, not a failure deep in the analysis.
    """
    nyquist_hz = manifest.sample_rate_hz / 2.0
    problems = []
    for i, entry in enumerate(manifest.steps):
        why = _frequency_problem(entry, nyquist_hz)
        if why is not None:
            line, column = locate(tree, ("steps", i, "frequency_hz"))
            problems.append(Problem(str(manifest_path), line, column, f"steps.{i}.frequency_hz",
                                    why))
    if problems:
        raise DatasetFileError(problems)


#: how far the declared sample rate may be from the files' own (median time step) rate
RATE_TOLERANCE = 2.0


def _check_rate(manifest: DatasetManifest, tree: Any, manifest_path: Path,
                parsed: list[tuple[CsvColumns, CsvColumns]]) -> None:
    """``sample_rate_hz`` within a factor :data:`RATE_TOLERANCE` of every file's time stamps.

    The analyses work in samples at the declared rate; a rate the files do not have (a typo,
    ``1e+308``) would make every frequency meaningless, so it is refused at its line.
    """
    declared = manifest.sample_rate_hz
    for csv in (c for pair in parsed for c in pair):
        steps_s = np.diff(csv.columns["time_s"])
        if steps_s.size == 0:
            continue
        actual = 1.0 / float(np.median(steps_s))
        if not 1.0 / RATE_TOLERANCE <= declared / actual <= RATE_TOLERANCE:
            line, column = locate(tree, ("sample_rate_hz",))
            raise DatasetFileError([Problem(
                str(manifest_path), line, column, "sample_rate_hz",
                f"{declared:g} Hz does not match {csv.path.name}, whose time stamps are "
                f"{actual:g} Hz apart (median)")])


#: data rows a CSV file needs: a time base is a line through at least two time stamps
MIN_ROWS = 2


def _file_of(directory: Path, manifest_path: Path, tree: Any, index: int, key: str,
             name: str) -> Path:
    path = directory / name
    if not path.is_file():
        line, column = locate(tree, ("steps", index, key))
        raise DatasetFileError([Problem(str(manifest_path), line, column, f"steps.{index}.{key}",
                                        f"file not found: {path}")])
    return path


def _table_log(entry: StepEntry, csv: CsvColumns, rate_hz: float) -> tuple[SampledLog, list[str]]:
    """Canonical table log of one step, and the channels the file really had."""
    n = len(csv)
    me, other = ("outer", "inner") if entry.axis == "outer" else ("inner", "outer")
    rest_deg = entry.inner_deg if other == "inner" else entry.outer_deg
    channels: dict[str, np.ndarray] = {f"{me}_{k}": csv.columns[k] for k in _MOTION}
    present = list(channels)
    for name in TABLE_CHANNELS:
        if name in csv.columns and name not in channels and name != "sync_pulse":
            channels[name] = csv.columns[name]
            present.append(name)
    for name, value in ((f"{other}_position_deg", rest_deg), (f"{other}_rate_dps", 0.0),
                        (f"{other}_accel_dps2", 0.0)):
        if name not in channels:
            channels[name] = _filled(n, value)
    for axis in ("inner", "outer"):
        channels.setdefault(f"{axis}_feedback_deg", channels[f"{axis}_position_deg"])
    channels["sync_pulse"] = csv.binary("sync_pulse")
    present.append("sync_pulse")
    ordered = {k: channels[k] for k in TABLE_CHANNELS if k in channels}
    units = {k: TABLE_CHANNELS[k] for k in ordered}
    return SampledLog(TABLE, rate_hz, csv.columns["time_s"], ordered, units), present


def _daq_log(entry: StepEntry, csv: CsvColumns, rate_hz: float, sensors: list[str],
             t_ref_c: float) -> tuple[SampledLog, list[str]]:
    channels: dict[str, np.ndarray] = {
        "sync_pulse": csv.binary("sync_pulse"),
        "trigger": csv.binary("trigger"),
    }
    channels.update({ch: csv.columns[ch] for ch in sensors})
    present = list(channels)
    if "temperature_c" in csv.columns:
        channels["temperature_c"] = plausible.temperature(csv)
        present.append("temperature_c")
    else:
        fill = entry.temperature_c if entry.temperature_c is not None else t_ref_c
        channels["temperature_c"] = _filled(len(csv), fill)
    units = {ch: "V" for ch in sensors} | {"sync_pulse": "1", "trigger": "1",
                                            "temperature_c": "degC"}
    return SampledLog(DAQ, rate_hz, csv.columns["time_s"], channels, units), present


def _filled(samples: int, value: float) -> np.ndarray:
    """A channel the file lacks, filled with what the step states; read-only, so that
    :class:`SampledLog` keeps it as it is instead of copying it."""
    values = np.full(samples, value, dtype=np.float64)
    values.flags.writeable = False
    return values


def _planned(entry: StepEntry, samples: int, rate_hz: float) -> PlannedStep:
    """The commanded step as a PlannedStep (sine amplitude A = α/(2πf)² when not given)."""
    amplitude = entry.amplitude_deg
    if entry.kind == "sine" and amplitude is None:
        assert entry.accel_dps2 is not None and entry.frequency_hz is not None  # validated
        amplitude = entry.accel_dps2 / (2 * math.pi * entry.frequency_hz) ** 2
    fields = entry.model_dump(exclude={"table", "daq", "file", "amplitude_deg"})
    return PlannedStep(**fields, amplitude_deg=amplitude, samples=samples,
                       sample_rate_hz=rate_hz, duration_s=samples / rate_hz)


def _t_ref_c(manifest: DatasetManifest, directory: Path) -> tuple[float, str | None]:
    """T_ref: the manifest's ``t_ref_c``, else the model file's, else 25 °C."""
    if manifest.t_ref_c is not None:
        return manifest.t_ref_c, manifest.model
    if manifest.model is None:
        return DEFAULT_T_REF_C, None
    model_path = directory / manifest.model
    try:
        _, data = parse_yaml(read_text(model_path), str(model_path))
    except ProblemsError as exc:
        raise DatasetFileError(exc.problems) from exc
    value = data.get("t_ref_c", DEFAULT_T_REF_C) if isinstance(data, dict) else DEFAULT_T_REF_C
    if not isinstance(value, (int, float)) or isinstance(value, bool):
        raise ImportDataError(model_path, f"t_ref_c must be a number, got {value!r}")
    return float(value), str(model_path)


def import_dataset(directory: str | Path) -> Dataset:
    """Read an import directory (docs/interfaces.md §3) into a :class:`Dataset`.

    Raises
    ------
    ImportDataError
        ``dataset.yaml`` or a CSV file is missing or malformed (file, line and what is wrong).
    """
    directory = Path(directory)
    manifest_path = directory / MANIFEST
    manifest, tree = load_manifest(manifest_path)
    _check_frequencies(manifest, tree, manifest_path)
    t_ref_c, model_file = _t_ref_c(manifest, directory)
    rate_hz = manifest.sample_rate_hz
    sensor_channels = [s.channel for s in manifest.sensors]
    parsed = _read_files(directory, manifest_path, tree, manifest)
    _check_rate(manifest, tree, manifest_path, parsed)
    steps, present = [], {}
    for entry, (table_csv, daq_csv) in zip(manifest.steps, parsed, strict=True):
        step, present[entry.id] = _step(entry, table_csv, daq_csv, rate_hz, sensor_channels,
                                        t_ref_c)
        steps.append(step)
    sensors = tuple(SensorInfo(**s.model_dump()) for s in manifest.sensors)  # the plain record
    return Dataset(
        procedure=manifest.procedure, sample_rate_hz=rate_hz, sensors=sensors,
        steps=tuple(steps), source=directory,
        metadata=_metadata(present, t_ref_c, model_file) | manifest.model_dump(
            include=set(STATED_KEYS), exclude_none=True)
        | rig_metadata(manifest),
    )


def rig_metadata(manifest: DatasetManifest) -> dict[str, Any]:
    """The ``rig`` block of the imported dataset's metadata: only what the file states.

    As a recording keeps its rig description, so a budget row tells a stated value from a
    declared or a default one (``exclude_unset``: a default stays a default after import).
    """
    rig: dict[str, Any] = {}
    if manifest.instruments is not None:
        rig["instruments"] = manifest.instruments.model_dump(mode="json", exclude_unset=True)
    if manifest.capabilities is not None:
        rig["capabilities"] = manifest.capabilities.model_dump(mode="json", exclude_unset=True)
    return {"rig": rig} if rig else {}


@dataclass(frozen=True)
class _CsvRead:
    """One CSV file to parse and the columns wanted from it."""

    path: Path
    required: tuple[str, ...]
    optional: tuple[str, ...]

    def __call__(self) -> CsvColumns:
        return read_csv(self.path, self.required, self.optional)


def _read_files(directory: Path, manifest_path: Path, tree: Any, manifest: DatasetManifest
                ) -> list[tuple[CsvColumns, CsvColumns]]:
    """Parse every step's table and DAQ file; return them in step order.

    Why this shape: the files are parsed by :data:`_READERS` threads (Arrow's parser holds no
    GIL), largest file first, so that the threads finish together instead of a step's small
    DAQ file leaving one of them idle; the results are still taken in manifest order, so the
    error reported is the one a sequential read meets first (a step's table file before its DAQ
    file, a missing file in its place). On an error the reads not yet started are cancelled.
    """
    daq_columns = DAQ_REQUIRED + tuple(s.channel for s in manifest.sensors)
    jobs: list[_CsvRead | ImportDataError] = []
    for i, entry in enumerate(manifest.steps):
        for key, name, required, optional in (
            ("table", entry.table, TABLE_REQUIRED, tuple(TABLE_CHANNELS)),
            ("daq", entry.daq, daq_columns, ("temperature_c",)),
        ):
            try:
                path = _file_of(directory, manifest_path, tree, i, key, name)
            except ImportDataError as exc:
                jobs.append(exc)
            else:
                jobs.append(_CsvRead(path, required, optional))
    reads = {k: job for k, job in enumerate(jobs) if isinstance(job, _CsvRead)}
    largest_first = sorted(reads, key=lambda k: -reads[k].path.stat().st_size)
    parsed: list[CsvColumns] = []
    with ThreadPoolExecutor(max_workers=_READERS, thread_name_prefix="csv") as pool:
        futures = {k: pool.submit(reads[k]) for k in largest_first}
        try:
            for k, job in enumerate(jobs):
                if isinstance(job, ImportDataError):
                    raise job
                parsed.append(futures[k].result())
        except BaseException:
            for future in futures.values():
                future.cancel()
            raise
    return list(zip(parsed[0::2], parsed[1::2], strict=True))


def _step(entry: StepEntry, table_csv: CsvColumns, daq_csv: CsvColumns, rate_hz: float,
          sensor_channels: list[str], t_ref_c: float
          ) -> tuple[StepData, dict[str, list[str]]]:
    """One step from its two parsed files, and the channels that really came from them."""
    for csv in (table_csv, daq_csv):
        if len(csv) < MIN_ROWS:
            raise ImportDataError(csv.path, f"{len(csv)} data row(s); a step needs at least "
                                            f"{MIN_ROWS} (its time base is fitted through them)",
                                  line=int(csv.row_lines[0]) if len(csv) else None)
    plausible.check_table(table_csv)
    plausible.check_volts(daq_csv, sensor_channels)
    table, table_present = _table_log(entry, table_csv, rate_hz)
    daq, daq_present = _daq_log(entry, daq_csv, rate_hz, sensor_channels, t_ref_c)
    return (StepData(_planned(entry, len(table), rate_hz), table, daq),
            {"table": table_present, "daq": daq_present})


def _metadata(present: dict[str, dict[str, list[str]]], t_ref_c: float,
              model_file: str | None) -> dict[str, Any]:
    return {
        "source_format": IMPORT_FORMAT,
        "complete": True,
        "t_ref_c": t_ref_c,
        "model_file": model_file,
        "columns_present": present,
        "fp_latch_s_present": all("fp_latch_s" in p["table"] for p in present.values()),
        "temperature_present": all("temperature_c" in p["daq"] for p in present.values()),
    }

