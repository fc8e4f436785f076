"""Measured data from a lab's logger: TDMS or MF4 files plus ``mapping.yaml`` → a Dataset.

The mapping (:mod:`aatest.recording.data.mapping`) is checked against the files before anything is
analysed: every group a step names, every mapped channel, its number type and (where the file
states one) its unit. All problems are reported at once, each at the ``FILE:LINE:COLUMN`` of the
mapping entry that is wrong and naming the data file and group where it looked. The numbers
themselves are read when an analysis reads a step (:class:`~aatest.recording.dataset.LazySteps`):
one step's two groups at a time, and only the channels asked for; a reduction over a long
record (:meth:`~aatest.recording.dataset.LazySteps.pieces`) reads :data:`PIECE_S` seconds at a
time, so such a record is never held whole. Each read opens the file anew: a forked analysis
worker then never shares a file position with its parent.

The resulting logs are those the CSV importer builds (:mod:`aatest.recording.data.importer`): the
same canonical channel names, units and fill-ins (the resting axis at its stated angle, feedback
equal to position, the stated temperature), so an analysis cannot tell the formats apart.
"""

from __future__ import annotations

from collections.abc import Container, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from aatest.engine.errors import ImportDataError, Problem
from aatest.engine.logs import DAQ, TABLE, TABLE_CHANNELS, SampledLog
from aatest.positioned_yaml import locate
from aatest.recording.data import plausible
from aatest.recording.data.importer import (
    STATED_KEYS,
    DatasetFileError,
    _filled,
    _metadata,
    _planned,
    _t_ref_c,
    rig_metadata,
)
from aatest.recording.data.logger_files import (
    AmbiguousGroupError,
    LoggerFile,
    LoggerGroup,
    open_logger_file,
)
from aatest.recording.data.mapping import (
    ChannelMap,
    LoggerMapping,
    MappedStep,
    PulseChannel,
    canonical_unit,
    load_mapping,
)
from aatest.recording.dataset import Dataset, LazySteps, SensorInfo, _subset

#: seconds of samples per piece of a piecewise read (as a streamed recording's blocks)
PIECE_S = 60.0
#: where each mapped channel's entry is in mapping.yaml, by canonical name
Specs = dict[str, tuple[ChannelMap, tuple[str, ...]]]
_MOTION = (("position", "position_deg"), ("rate", "rate_dps"), ("accel", "accel_dps2"))


def table_specs(mapping: LoggerMapping, axis: str) -> Specs:
    """The table channels a step of ``axis`` maps, by canonical name (time under ``time_s``)."""
    me = "outer" if axis == "outer" else "inner"
    table = mapping.table
    specs: Specs = {}
    if table.time is not None:
        specs["time_s"] = (table.time, ("table", "time"))
    for key, suffix in _MOTION:
        specs[f"{me}_{suffix}"] = (getattr(table, key), ("table", key))
    for name in type(table.channels).model_fields:
        spec = getattr(table.channels, name)
        if spec is not None and name not in specs:
            specs[name] = (spec, ("table", "channels", name))
    specs["sync_pulse"] = (table.freeze_pulse, ("table", "freeze_pulse"))
    if table.fp_latch_s is not None:
        specs["fp_latch_s"] = (table.fp_latch_s, ("table", "fp_latch_s"))
    return specs


def daq_specs(mapping: LoggerMapping) -> Specs:
    """The DAQ channels every step maps, by canonical name."""
    daq = mapping.daq
    specs: Specs = {}
    if daq.time is not None:
        specs["time_s"] = (daq.time, ("daq", "time"))
    specs["sync_pulse"] = (daq.freeze_pulse, ("daq", "freeze_pulse"))
    specs["trigger"] = (daq.trigger, ("daq", "trigger"))
    for channel, spec in mapping.sensor_map().items():
        specs[channel] = (spec, ("daq", "sensors", channel))
    if daq.temperature is not None:
        specs["temperature_c"] = (daq.temperature, ("daq", "temperature"))
    return specs


@dataclass(frozen=True)
class _Side:
    """One step's table or DAQ group as checked: where it is and which channels it has."""

    file: Path
    group: str | int
    #: canonical name → mapping of the channels the group really has
    specs: Specs
    samples: int


@dataclass
class _Checker:
    """Collects located problems of the mapping against its files."""

    mapping_path: Path
    tree: Any
    problems: list[Problem]

    def add(self, where: tuple[Any, ...], message: str) -> None:
        line, column = locate(self.tree, where)
        self.problems.append(Problem(str(self.mapping_path), line, column,
                                     ".".join(map(str, where)), message))


def import_logger_files(mapping_path: str | Path) -> Dataset:
    """Read ``mapping.yaml`` and the TDMS/MF4 files it names into a :class:`Dataset`.

    Raises
    ------
    ImportDataError
        The mapping is malformed or does not fit the files (``FILE:LINE:COLUMN`` each), or a
        data file is missing, damaged or truncated (naming the file).
    """
    mapping_path = Path(mapping_path)
    mapping, tree = load_mapping(mapping_path)
    directory = mapping_path.parent
    checker = _Checker(mapping_path, tree, [])
    sides = _check_files(mapping, directory, checker)
    if checker.problems:
        raise DatasetFileError(checker.problems)
    t_ref_c, model_file = _t_ref_c(mapping, directory)
    rate_hz = mapping.sample_rate_hz
    planned = [_planned(entry, table.samples, rate_hz)
               for entry, (table, _) in zip(mapping.steps, sides, strict=True)]
    loader = _Loader(mapping, sides, t_ref_c)
    steps = LazySteps(planned, loader, [{"table": t.samples, "daq": d.samples}
                                        for t, d in sides], loader.pieces)
    present = {entry.id: {"table": _present_table(entry, table), "daq": list(daq.specs)}
               for entry, (table, daq) in zip(mapping.steps, sides, strict=True)}
    for names in present.values():
        names["daq"] = [n for n in names["daq"] if n != "time_s"]
    metadata = _metadata(present, t_ref_c, model_file) | {
        "source_format": f"aatest.import/{mapping.format}"}
    metadata |= mapping.model_dump(include=set(STATED_KEYS), exclude_none=True)
    metadata |= rig_metadata(mapping)  # only what the mapping states
    return Dataset(procedure=mapping.procedure, sample_rate_hz=rate_hz,
                   sensors=tuple(SensorInfo(**s.model_dump()) for s in mapping.sensors),
                   steps=steps, source=directory, metadata=metadata)


def _present_table(entry: MappedStep, table: _Side) -> list[str]:
    """The table channels that come from the file, in the CSV importer's order."""
    me = "outer" if entry.axis == "outer" else "inner"
    moving = [f"{me}_{suffix}" for _, suffix in _MOTION]
    rest = [n for n in table.specs if n not in moving and n not in ("time_s", "sync_pulse")]
    return moving + rest + ["sync_pulse"]


def _data_file(mapping: LoggerMapping, directory: Path, index: int, entry: MappedStep,
               checker: _Checker) -> Path | None:
    name, where = ((entry.file, ("steps", index, "file")) if entry.file is not None
                   else (mapping.file, ("file",)))
    if name is None:
        checker.add(("steps", index), "no data file: give top-level 'file' or the step's 'file'")
        return None
    path = directory / name
    if not path.is_file():
        checker.add(where, f"file not found: {path}")
        return None
    return path


def _check_files(mapping: LoggerMapping, directory: Path, checker: _Checker
                 ) -> list[tuple[_Side, _Side]]:
    """Check every step's groups and channels; open each data file once."""
    names = {s.channel for s in mapping.sensors}
    for channel in mapping.daq.sensors:
        if channel not in names:
            checker.add(("daq", "sensors", channel), "not a channel of 'sensors'")
    files = [_data_file(mapping, directory, i, e, checker) for i, e in enumerate(mapping.steps)]
    sides: dict[int, tuple[_Side, _Side]] = {}
    for path in dict.fromkeys(p for p in files if p is not None):
        with open_logger_file(path, mapping.format) as opened:
            for i, entry in enumerate(mapping.steps):
                if files[i] == path:
                    table = _check_group(opened, i, "table", entry.table,
                                         table_specs(mapping, entry.axis), checker)
                    daq = _check_group(opened, i, "daq", entry.daq, daq_specs(mapping), checker)
                    if table is not None and daq is not None:
                        sides[i] = (table, daq)
    return [sides[i] for i in range(len(mapping.steps)) if i in sides]


def _check_group(opened: LoggerFile, index: int, side: str, key: str | int, specs: Specs,
                 checker: _Checker) -> _Side | None:
    try:
        group = opened.group(key)
    except AmbiguousGroupError as exc:
        checker.add(("steps", index, side), str(exc))
        return None
    if group is None:
        checker.add(("steps", index, side), f"no group {key!r} in {opened.path} "
                    f"(it has: {', '.join(opened.group_names()) or 'none'})")
        return None
    before = len(checker.problems)
    channels = group.channels()
    found: Specs = {}
    for name, (spec, where) in specs.items():
        info = channels.get(spec.channel)
        what = f"channel {spec.channel!r} of group {key!r} in {opened.path}"
        if info is None:
            if spec.required:
                checker.add((*where, "channel"), f"no {what} (it has: {', '.join(channels)})")
            continue
        if info.dtype.kind not in "biuf":
            checker.add((*where, "channel"), f"{what} holds {info.dtype} values, not numbers")
        _check_unit(spec, info.unit, where, what, checker)
        found[name] = (spec, where)
    lengths = {channels[s.channel].samples for s, _ in found.values()}
    if len(lengths) > 1:
        checker.add(("steps", index, side), f"the mapped channels of group {key!r} in "
                    f"{opened.path} differ in length ({sorted(lengths)} samples)")
    pulse = specs["sync_pulse"][0].channel
    if "time_s" not in specs and pulse in channels and not group.has_time_base(pulse):
        checker.add((side,), f"group {key!r} in {opened.path} has no time base of its own "
                    f"(channel {pulse!r}): map a time channel under '{side}.time'")
    if len(checker.problems) > before:
        return None
    samples = lengths.pop() if lengths else 0
    return _Side(opened.path, key, found, samples)


def _check_unit(spec: ChannelMap, stated: str, where: tuple[str, ...], what: str,
                checker: _Checker) -> None:
    """A file that states a different unit of the same quantity than the mapping, with no
    scaling between them, is a mapping error (radians read as degrees)."""
    unit = getattr(spec, "unit", None)
    file_unit = canonical_unit(stated)
    if (unit is None or (spec.gain, spec.offset) != (1.0, 0.0) or file_unit == unit
            or file_unit not in type(spec).units()):
        return
    checker.add((*where, "unit"), f"{what} is in {stated!r} by the file, the mapping says "
                f"{unit!r} (fix the unit, or give gain/offset)")


class _Loader:
    """``load(index, source, channels)`` of :class:`LazySteps` over the checked files."""

    def __init__(self, mapping: LoggerMapping, sides: list[tuple[_Side, _Side]],
                 t_ref_c: float) -> None:
        self._steps = mapping.steps
        self._format = mapping.format
        self._rate_hz = mapping.sample_rate_hz
        self._sides = sides
        self._t_ref_c = t_ref_c
        self._sensors = [s.channel for s in mapping.sensors]

    def __call__(self, index: int, source: str, channels: Container[str] | None) -> SampledLog:
        return self._read(index, source, channels, 0, None)

    def pieces(self, index: int, source: str, channels: Container[str] | None
               ) -> Iterator[SampledLog]:
        """The log in consecutive pieces of :data:`PIECE_S` seconds (one file read each)."""
        side = self._sides[index][0 if source == TABLE else 1]
        step = max(1, int(PIECE_S * self._rate_hz))
        last_s = -np.inf
        for start in range(0, max(side.samples, 1), step):
            piece = self._read(index, source, channels, start, min(step, side.samples - start))
            if len(piece) and not piece.time_s[0] > last_s:
                raise ImportDataError(side.file, f"group {side.group!r}: time does not "
                                      f"increase at sample {start}")
            last_s = piece.time_s[-1] if len(piece) else last_s
            yield piece

    def _read(self, index: int, source: str, channels: Container[str] | None, start: int,
              length: int | None) -> SampledLog:
        entry = self._steps[index]
        side = self._sides[index][0 if source == TABLE else 1]
        wanted = {n: s for n, (s, _) in side.specs.items()
                  if n == "time_s" or channels is None or n in channels
                  or fills_feedback(n, channels)}  # a feedback fill copies its position
        with open_logger_file(side.file, self._format) as opened:
            group = opened.group(side.group)
            assert group is not None  # checked on import; the file may not change meanwhile
            values = {name: _converted(group, side, name, spec, start, length,
                                           self._sensors)
                      for name, spec in wanted.items()}
            if "time_s" not in values:
                values["time_s"] = group.time_base(side.specs["sync_pulse"][0].channel, start,
                                                   length)
        time_s = values.pop("time_s")
        _check_time(side, time_s, start)
        asked = _Everything() if channels is None else channels
        log = self._table(entry, time_s, values, asked) if source == TABLE else self._daq(
            entry, time_s, values, asked)
        return log if channels is None else _subset(log, channels)

    def _table(self, entry: MappedStep, time_s: np.ndarray, values: dict[str, np.ndarray],
               asked: Container[str]) -> SampledLog:
        """The table log with the CSV importer's fill-ins for channels the file lacks (only
        those asked for: a fill of a long record is as large as a channel)."""
        other = "inner" if entry.axis == "outer" else "outer"
        rest_deg = entry.inner_deg if other == "inner" else entry.outer_deg
        fills = {f"{other}_position_deg": rest_deg, f"{other}_rate_dps": 0.0,
                 f"{other}_accel_dps2": 0.0}
        feedback_of = {f"{a}_feedback_deg": f"{a}_position_deg" for a in ("inner", "outer")}
        for name, value in fills.items():
            if name not in values and (name in asked or fills_feedback(name, asked)):
                values[name] = _filled(len(time_s), value)
        for name, position in feedback_of.items():
            if name not in values and name in asked:
                values[name] = values[position]
        ordered = {k: values[k] for k in TABLE_CHANNELS if k in values}
        return SampledLog(TABLE, self._rate_hz, time_s, ordered,
                          {k: TABLE_CHANNELS[k] for k in ordered})

    def _daq(self, entry: MappedStep, time_s: np.ndarray, values: dict[str, np.ndarray],
             asked: Container[str]) -> SampledLog:
        if "temperature_c" not in values and "temperature_c" in asked:
            fill = entry.temperature_c if entry.temperature_c is not None else self._t_ref_c
            values["temperature_c"] = _filled(len(time_s), fill)
        order = ["sync_pulse", "trigger", *self._sensors, "temperature_c"]
        ordered = {k: values[k] for k in order if k in values}
        units = {k: ("V" if k in self._sensors else {"temperature_c": "degC"}.get(k, "1"))
                 for k in ordered}
        return SampledLog(DAQ, self._rate_hz, time_s, ordered, units)


class _Everything(Container[str]):
    """Every channel name (a load with no selection)."""

    def __contains__(self, name: object) -> bool:
        return True


def fills_feedback(position: str, asked: Container[str]) -> bool:
    """Whether ``position`` is needed for the feedback fill of its axis."""
    return position.endswith("_position_deg") and position.replace("position",
                                                                    "feedback") in asked


def _converted(group: LoggerGroup, side: _Side, name: str, spec: ChannelMap, start: int,
               length: int | None, sensors: list[str]) -> np.ndarray:
    """One channel in aatest's unit: a 0/1 pulse as uint8, anything else as float64 within
    the physically possible range of its quantity (:mod:`~aatest.recording.data.plausible`,
    as the CSV import holds it)."""
    raw = group.read(spec.channel, start, length)
    where = f"group {side.group!r}, channel {spec.channel!r}"
    if isinstance(spec, PulseChannel):
        return _pulse(side.file, where, raw, spec.threshold, start)
    values = raw.astype(np.float64, copy=False)
    factor, shift = spec.scaling()
    if (factor, shift) != (1.0, 0.0):
        values = values * factor + shift
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        raise ImportDataError(side.file, f"{where}: sample {start + int(bad[0])} is not a finite "
                              f"number ({float(values[bad[0]])!r})")
    plausible.check_samples(side.file, where, name, values, start, sensors)
    values.flags.writeable = False
    return values


def _pulse(path: Path, where: str, raw: np.ndarray, threshold: float | None, start: int
           ) -> np.ndarray:
    """A 0/1 line: a logic channel as it is, or an analogue one cut at ``threshold``."""
    if threshold is not None:
        pulse = (raw > threshold).astype(np.uint8)
    else:
        bad = np.flatnonzero((raw != 0) & (raw != 1))
        if bad.size:
            found = float(raw[bad[0]])
            raise ImportDataError(path, f"{where}: must be 0 or 1, found {found!r} at sample "
                                  f"{start + int(bad[0])} (an analogue line needs 'threshold')")
        pulse = raw.astype(np.uint8)
    pulse.flags.writeable = False
    return pulse


def _check_time(side: _Side, time_s: np.ndarray, start: int) -> None:
    bad = np.flatnonzero(~(np.diff(time_s) > 0))
    if bad.size or not np.all(np.isfinite(time_s[:1])):
        k = start + (int(bad[0]) + 1 if bad.size else 0)
        raise ImportDataError(side.file, f"group {side.group!r}: time does not increase at "
                              f"sample {k}")
