"""The one input every analysis reads: steps with their two raw logs and the sensors' nominals.

A :class:`Dataset` is built either from an aatest recording (``recording.mcap``) or from a
measured-data import directory (docs/interfaces.md §3), so analyses and ``diagnose`` never care
where the data came from and can always be re-run offline. Its per-channel sensor record,
:class:`SensorInfo`, is defined with the datasheet it comes from in
:mod:`aatest.engine.datasheet` and re-exported here.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Container, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, overload

from aatest.engine.datasheet import SensorAxis, SensorInfo
from aatest.engine.logs import SampledLog
from aatest.engine.steps import PlannedStep
from aatest.recording import extremes

if TYPE_CHECKING:
    from aatest.storage.location import RemotePath

__all__ = ["Dataset", "LazySteps", "NamesStartingWith", "SensorAxis", "SensorInfo", "StepData",
           "StepWatch"]

#: ``load(index, source, channels)``: the ``"table"`` or ``"daq"`` log of the step at ``index``
#: (only the channels named in ``channels`` and the time stamps when not None)
LogLoader = Callable[[int, str, Container[str] | None], SampledLog]
#: ``pieces(index, source, channels)``: the same log as consecutive pieces, in sample order
PieceLoader = Callable[[int, str, Container[str] | None], Iterator[SampledLog]]


@dataclass(frozen=True)
class NamesStartingWith(Container[str]):
    """Every channel name that starts with ``prefix``: a selection for :meth:`LazySteps.partial`
    when the names are not known before decoding (e.g. every ``temperature*`` channel).

    Only membership is defined, which is all a partial decode asks of a selection.
    """

    prefix: str

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and name.startswith(self.prefix)


@dataclass(frozen=True)
class StepData:
    """One recorded step: what was commanded and what both loggers saw."""

    step: PlannedStep
    table: SampledLog
    daq: SampledLog

    def samples(self, source: str) -> int:
        """Sample count (samples, no unit) of the ``"table"`` or ``"daq"`` log."""
        return len(self.table if source == "table" else self.daq)

    def daq_extremes(self) -> dict[str, extremes.Extremes]:
        """Each sensor channel's ``[least, samples at it, largest, samples at it]``
        (:mod:`aatest.recording.extremes`)."""
        return extremes.of_log(self.daq)


class LazyStepData(StepData):
    """A recorded step whose two logs are decoded from their source when first read.

    Why: a stepped-sine recording decodes to gigabytes; a dataset of these holds only the
    planned steps, and a log lives as long as the caller holds its step (docs/architecture.md,
    bounded memory). Each log is decoded at most once per object.
    """

    def __init__(self, step: PlannedStep, index: int, load: LogLoader,
                 samples: Mapping[str, int],
                 extremes_of: Callable[[], dict[str, extremes.Extremes]] | None = None
                 ) -> None:
        object.__setattr__(self, "step", step)
        object.__setattr__(self, "_index", index)
        object.__setattr__(self, "_load", load)
        object.__setattr__(self, "_samples", dict(samples))
        object.__setattr__(self, "_extremes_of", extremes_of)
        object.__setattr__(self, "_logs", {})

    def _log(self, source: str) -> SampledLog:
        logs: dict[str, SampledLog] = self.__dict__["_logs"]
        if source not in logs:
            logs[source] = self.__dict__["_load"](self.__dict__["_index"], source, None)
        return logs[source]

    @property  # overrides the read-only field: computed on first access
    def table(self) -> SampledLog:
        """The table controller's log (decoded now if not yet)."""
        return self._log("table")

    @property  # overrides the read-only field: computed on first access
    def daq(self) -> SampledLog:
        """The sensor logger's log (decoded now if not yet)."""
        return self._log("daq")

    def samples(self, source: str) -> int:
        """Sample count (samples, no unit) of a log, from its record: nothing is decoded."""
        known: dict[str, int] = self.__dict__["_samples"]
        return known[source] if source in known else len(self._log(source))

    def daq_extremes(self) -> dict[str, extremes.Extremes]:
        """The sensor channels' extremes: as the step record notes them, else found by a
        decode of the sensor channels only (piece by piece where the source allows it)."""
        extremes_of: Callable[[], dict[str, extremes.Extremes]] | None = (
            self.__dict__["_extremes_of"])
        if extremes_of is None:
            return super().daq_extremes()
        return extremes_of()

    def __repr__(self) -> str:
        return f"LazyStepData(step={self.step.id!r}, index={self.__dict__['_index']})"


@dataclass(frozen=True)
class StepWatch:
    """A small per-step reduction that rides along the first partial decode of a step.

    Why: several passes read the same recorded step (the sync pass, the analyses, the
    uncertainty evidence), each decoding only its channels; every decode costs a fixed part
    (reading, CRC, decompressing and parsing every block) whatever the channels. A pass that
    will need a step later registers a watch (:meth:`LazySteps.watch`); the first
    :meth:`LazySteps.partial` of that step decodes the union of the channels and runs the
    reduction then, so the later pass reads its small result instead of decoding again.
    Results must be small (a few numbers): memory holds one per watched step.

    Parameters
    ----------
    channels
        The channels the reduction reads of a planned step, by source (``"table"``/``"daq"``).
    applies
        Whether the reduction is wanted for a planned step (others decode nothing extra).
    reduce
        The reduction of the decoded step (the union of the channels, and the time stamps).
    """

    channels: Callable[[PlannedStep], Mapping[str, Container[str]]]
    applies: Callable[[PlannedStep], bool]
    reduce: Callable[[StepData], Any]


#: the result kept for a reduction that raised
_FAILED = object()


def _guarded(watch: StepWatch) -> StepWatch:
    """``watch`` whose reduction, if it raises, leaves :data:`_FAILED` (never breaks the
    decode it rides along)."""

    def reduce(step: StepData) -> Any:
        try:
            return watch.reduce(step)
        except Exception:  # noqa: BLE001 - the owner recomputes the step and meets the error
            return _FAILED

    return StepWatch(watch.channels, watch.applies, reduce)


@dataclass(frozen=True)
class _Union(Container[str]):
    """Every name in any of ``parts`` (a selection for a decode serving several readers)."""

    parts: tuple[Container[str], ...]

    def __contains__(self, name: object) -> bool:
        return any(name in part for part in self.parts)


def _subset(log: SampledLog, channels: Container[str]) -> SampledLog:
    """The log with only ``channels`` (views, in the logged order): what a decode of only
    those channels gives."""
    kept = {name: values for name, values in log.channels.items() if name in channels}
    return SampledLog(log.source, log.sample_rate_hz, log.time_s, kept,
                      {k: v for k, v in log.units.items() if k in kept},
                      {k: v for k, v in log.quantisation.items()
                       if k == "time_s" or k in kept})


class LazySteps(Sequence[StepData]):
    """The steps of a recording, decoded one at a time when an element is read.

    Indexing returns a fresh :class:`LazyStepData`: iterating holds one step's logs at a time,
    whatever the number of steps, and filtering on ``.step`` (kind, group, ...) decodes
    nothing. ``planned`` gives the planned steps without building step objects.
    """

    def __init__(self, planned: Sequence[PlannedStep], load: LogLoader,
                 samples: Sequence[Mapping[str, int]], pieces: PieceLoader | None = None,
                 noted_extremes: Sequence[Mapping[str, extremes.Extremes] | None] | None = None
                 ) -> None:
        if len(samples) != len(planned):
            raise ValueError("one sample-count record per planned step is needed")
        if noted_extremes is not None and len(noted_extremes) != len(planned):
            raise ValueError("one extremes record (or None) per planned step is needed")
        self._noted_extremes = tuple(noted_extremes or (None,) * len(planned))
        self.planned = tuple(planned)
        self._load = load
        self._pieces = pieces
        self._samples = tuple(samples)
        #: registered watches and their results by step index
        self._watches: dict[str, tuple[StepWatch, dict[int, Any]]] = {}

    def __len__(self) -> int:
        return len(self.planned)

    @overload
    def __getitem__(self, index: int) -> StepData: ...

    @overload
    def __getitem__(self, index: slice) -> Sequence[StepData]: ...

    def __getitem__(self, index: int | slice) -> StepData | Sequence[StepData]:
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(len(self)))]
        i = range(len(self))[index]  # IndexError and negative indices as for a tuple
        return LazyStepData(self.planned[i], i, self._load, self._samples[i],
                            functools.partial(self._extremes, i))

    def __iter__(self) -> Iterator[StepData]:
        return (self[i] for i in range(len(self)))

    def _extremes(self, index: int) -> dict[str, extremes.Extremes]:
        """Step ``index``'s sensor-channel extremes: the record's note (written since the
        recording noted them), else a decode of the sensor channels alone."""
        noted = self._noted_extremes[index]
        if noted is not None:
            return {name: list(values) for name, values in noted.items()}
        sensors = NamesStartingWith(extremes.SENSOR_PREFIX)
        if self._pieces is None:
            return extremes.of_log(self._load(index, "daq", sensors))
        found: dict[str, extremes.Extremes] = {}
        for piece in self._pieces(index, "daq", sensors):
            found = extremes.merged_logs(found, extremes.of_log(piece))
        return found

    def partial(self, index: int, channels: Mapping[str, Container[str]]) -> StepData:
        """Step ``index`` with only some channels decoded (and the time stamps), by source.

        Why: a pass that reads a few channels of every step (the sync pulses) decodes a
        fraction of the data. ``channels`` maps ``"table"``/``"daq"`` to channel names (a
        collection, or :class:`NamesStartingWith`); a source not named decodes no channel.
        Names a log does not have are ignored.
        """
        i = range(len(self))[index]
        step = self.planned[i]
        due = [(watch, done) for watch, done in self._watches.values()
               if i not in done and watch.applies(step)]
        if not due:
            logs = {source: self._load(i, source, channels.get(source, ()))
                    for source in ("table", "daq")}
            return StepData(step, logs["table"], logs["daq"])
        wanted = {source: _Union((channels.get(source, ()),
                                  *(watch.channels(step).get(source, ()) for watch, _ in due)))
                  for source in ("table", "daq")}
        whole = StepData(step, *(self._load(i, source, wanted[source])
                                 for source in ("table", "daq")))
        for watch, done in due:
            done[i] = watch.reduce(whole)
        return StepData(step, *(_subset(whole.table if source == "table" else whole.daq,
                                        channels.get(source, ()))
                                for source in ("table", "daq")))

    def watch(self, name: str, watch: StepWatch) -> None:
        """Run ``watch`` on each step it applies to when that step is first decoded partly.

        Registering a name again keeps the results already made under it. A reduction that
        raises is not kept (its owner computes it again, and meets the error there).
        """
        if name not in self._watches:
            self._watches[name] = (_guarded(watch), {})

    def watched(self, name: str, index: int) -> Any:
        """The result of watch ``name`` for step ``index``.

        Raises
        ------
        KeyError
            When that step has not been decoded since the watch was registered (or its
            reduction failed): the owner then reads the step itself.
        """
        result = self._watches[name][1][index]
        if result is _FAILED:
            raise KeyError(index)
        return result

    def kept(self, index: int) -> dict[str, Any]:
        """Every watch's result for step ``index`` by watch name (those made and not failed):
        what a worker process that decoded the step hands back, see :meth:`keep`."""
        return {name: done[index] for name, (_, done) in self._watches.items()
                if done.get(index, _FAILED) is not _FAILED}

    def keep(self, index: int, results: Mapping[str, Any]) -> None:
        """Take watch results for step ``index`` made elsewhere (a forked worker's
        :meth:`kept`), as if this object had decoded the step."""
        for name, result in results.items():
            if name in self._watches:
                self._watches[name][1][index] = result

    def log(self, index: int, source: str, channels: Container[str] | None = None
            ) -> SampledLog:
        """The ``"table"`` or ``"daq"`` log of step ``index``, decoded now, with the time
        stamps and only ``channels`` (all when None); no watch runs. Why: a view of these
        steps in another dataset (:mod:`aatest.early.analysis`) loads through it."""
        return self._load(range(len(self))[index], source, channels)

    def pieces(self, index: int, source: str, channels: Container[str] | None = None
               ) -> Iterator[SampledLog]:
        """The ``"table"`` or ``"daq"`` log of step ``index`` as consecutive pieces in sample
        order (the recorded blocks: 60 s each of a streamed DAQ record), with the time stamps
        and only ``channels`` (all when None).

        Why: a reduction of an hours-long record (block means, a sum, the first samples) holds
        one piece at a time, not 115 MB per channel. Stop iterating early to decode no more.
        A source without piecewise reading yields the whole log as one piece.
        """
        i = range(len(self))[index]
        if self._pieces is None:
            yield self._load(i, source, channels)
            return
        yield from self._pieces(i, source, channels)


@dataclass(frozen=True)
class Dataset:
    """Everything an analysis may read."""

    procedure: str
    sample_rate_hz: float
    sensors: tuple[SensorInfo, ...]
    #: a tuple, or :class:`LazySteps` (a recording: each step decoded when read)
    steps: Sequence[StepData]
    #: where it was read from: a local path, or a location on object storage
    source: Path | RemotePath
    metadata: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "metadata", MappingProxyType(dict(self.metadata)))
        if not isinstance(self.steps, (tuple, LazySteps)):
            object.__setattr__(self, "steps", tuple(self.steps))

    def sensor(self, channel: str) -> SensorInfo:
        """The sensor recorded on DAQ ``channel`` (its axis, serial and nominal scale in V/(°/s²)).

        Analyses address sensors by the logger channel their volts arrive on, because that is
        what a recording stores; a channel without a sensor is a ``KeyError``, not a guess.
        """
        for info in self.sensors:
            if info.channel == channel:
                return info
        raise KeyError(channel)

    @property
    def planned(self) -> tuple[PlannedStep, ...]:
        """The planned step of every recorded step, in order, without decoding any log."""
        if isinstance(self.steps, LazySteps):
            return self.steps.planned
        return tuple(s.step for s in self.steps)

    def steps_of_kind(self, kind: str) -> list[StepData]:
        """The steps of one kind (``"sine"``, ``"static"`` …); lazy steps stay undecoded."""
        return [s for s in self.steps if s.step.kind == kind]
