"""The plugin interfaces, one ``Protocol`` per kind and one entry-point group per kind.

Flow: the runner asks the *chamber* for a temperature, the *turntable* to move and record, the
*daq* to record the sensors and emit the sync pulse/trigger; the recording is then read back
by *analysis* plugins (ordered by what each ``requires``) and their results rendered by a
*report* plugin.

Every rig plugin class has a nested pydantic ``Config`` (``extra="forbid"``) and is constructed
as ``PluginClass(config, context)``; an analysis plugin has ``Options`` instead and is
constructed without arguments. Simulated plugins share the digital twin through
``RigContext.resources`` (one object per type); real drivers ignore it. The sensor datasheet
is defined in :mod:`aatest.engine.datasheet` and re-exported here.

Constructing a rig plugin does no I/O: ``validate`` and ``plan`` build the rig only to read its
declarations (``envelope``, the optional ``capabilities`` and ``cannot_follow``) and never
start, stop or close it. Optional methods (absent on older plugins, found with ``getattr``):
``Turntable.capabilities()`` (:func:`table_capabilities`), ``Turntable.status()``
(:class:`StatusTable`, :func:`table_status`), ``Daq.cannot_follow(turntable)``
(:func:`daq_refusal`), ``Daq.stream_logging`` (:class:`StreamingDaq`). The whole contract:
docs/vendor-plugins.md, "The plugin contract".
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import (
    TYPE_CHECKING,
    Any,
    ClassVar,
    Generic,
    Literal,
    Protocol,
    TypeVar,
    runtime_checkable,
)

from pydantic import BaseModel, ConfigDict, Field, field_validator

from aatest.engine.capabilities import TableCapabilities
from aatest.engine.datasheet import SensorDatasheet
from aatest.engine.logs import SampledLog
from aatest.engine.requirements import Requirement
from aatest.engine.steps import PlannedStep, SensorRef
from aatest.recording.dataset import Dataset
from aatest.results import RunResults
from aatest.rig_defaults import (
    INNER_ACCEL_DPS2,
    INNER_RATE_DPS,
    LOG_CAPACITY_SAMPLES,
    LOG_RATE_HZ,
    OUTER_ACCEL_DPS2,
    OUTER_RATE_DPS,
)

if TYPE_CHECKING:
    from aatest.engine.rig_description import Instruments

# The public names; SensorDatasheet is re-exported (sensor plugins return it).
__all__ = [
    "GROUPS", "Analysis", "AnalysisContext", "AnalysisOutput", "AxisLimits", "AxisName",
    "Chamber", "Daq", "DeclaresNeeds", "NoOptions", "PdfRenderer", "Reporter", "RigContext",
    "SensorDatasheet", "SensorPlugin", "SharedResources", "StatusTable", "TableCapabilities",
    "TableEnvelope", "TableStatus", "Turntable", "daq_refusal", "reports_status",
    "table_capabilities", "table_status",
]

#: entry-point group per plugin kind
GROUPS: dict[str, str] = {
    "turntable": "aatest.turntables",
    "daq": "aatest.daqs",
    "chamber": "aatest.chambers",
    "sensor": "aatest.sensors",
    "analysis": "aatest.analyses",
    "report": "aatest.reports",
    "effect": "aatest.effects",  # diagnose's open effect vocabulary (aatest.effects.Effect)
}


class AxisLimits(BaseModel):
    """Limits of one table axis; ``continuous`` axes have no position stops."""

    model_config = ConfigDict(frozen=True, extra="forbid")
    rate_dps: float = Field(gt=0)
    accel_dps2: float = Field(gt=0)
    continuous: bool = True
    min_deg: float = -180.0
    max_deg: float = 180.0


#: a table axis as aatest names it (a single-axis table's one axis is ``inner``)
AxisName = Literal["inner", "outer"]


class TableEnvelope(BaseModel):
    """What a turntable can do; the planner checks every step against it.

    ``axes`` lists the axes the table has: a single-axis table declares ``("inner",)`` and every
    step that moves or positions the outer axis is refused at ``validate`` with that reason (the
    limits of an absent axis are not read).
    """

    model_config = ConfigDict(frozen=True, extra="forbid")
    inner: AxisLimits = AxisLimits(rate_dps=INNER_RATE_DPS, accel_dps2=INNER_ACCEL_DPS2)
    outer: AxisLimits = AxisLimits(rate_dps=OUTER_RATE_DPS, accel_dps2=OUTER_ACCEL_DPS2)
    axes: tuple[AxisName, ...] = ("inner", "outer")
    max_log_rate_hz: float = LOG_RATE_HZ
    log_capacity_samples: int = LOG_CAPACITY_SAMPLES
    #: usable terminal frequency with payload (docs/method.md §1.2: 10 Hz, not 11.25 Hz)
    max_frequency_hz: float = 10.0
    #: the rig's DAQ streams long records (:class:`StreamingDaq`); set by the engine from the
    #: DAQ plugin, not by the turntable: a static step may then exceed ``log_capacity_samples``
    streaming_daq: bool = False

    @field_validator("axes")
    @classmethod
    def _inner_present(cls, axes: tuple[AxisName, ...]) -> tuple[AxisName, ...]:
        if "inner" not in axes or len(set(axes)) != len(axes):
            raise ValueError("axes must name 'inner' (a single-axis table's axis) and each "
                             "axis once, e.g. ['inner'] or ['inner', 'outer']")
        return axes


_T = TypeVar("_T")


class SharedResources:
    """Objects the plugins of one rig share, at most one per type.

    Keyed by class rather than by string, so a plugin asks for exactly the type it needs and a
    type checker sees what comes back. The simulated plugins share their digital-twin session
    here (:class:`aatest.twin.session.TwinSession`); real drivers ignore it.
    """

    def __init__(self) -> None:
        self._by_type: dict[type, object] = {}

    def get(self, kind: type[_T]) -> _T | None:
        """The shared object of type ``kind``, or None when no plugin made one yet."""
        found = self._by_type.get(kind)
        return found if isinstance(found, kind) else None

    def setdefault(self, kind: type[_T], make: Callable[[], _T]) -> _T:
        """The shared object of type ``kind``; ``make()`` creates it when there is none."""
        found = self.get(kind)
        if found is None:
            found = make()
            if not isinstance(found, kind):
                raise TypeError(f"shared resource for {kind.__name__} is a "
                                f"{type(found).__name__}")
            self._by_type[kind] = found
        return found


@dataclass
class RigContext:
    """What the engine hands every rig plugin at construction.

    ``datasheet`` is the resolved sensor plugin's datasheet (channels, range, nominals);
    ``resources`` holds what the plugins of this rig share (the simulated ones: the twin).
    """

    sensor: SensorRef
    datasheet: SensorDatasheet
    seed: int = 0
    resources: SharedResources = field(default_factory=SharedResources)
    #: the rig description's stated instruments, when the rig YAML states them (a simulated
    #: logger then converts as the stated one does)
    instruments: Instruments | None = None


@runtime_checkable
class SensorPlugin(Protocol):
    """A sensor model: its datasheet (the twin derives its realistic error model from it)."""

    def datasheet(self) -> SensorDatasheet:
        """Return the sensor's datasheet: channels, range (°/s²), nominal scale factor and bias.

        The one source of the sensor's numbers: the planner checks steps against its range,
        the verdict stage takes its default limits from it, the twin derives its error model.
        """


@runtime_checkable
class Turntable(Protocol):
    """A motion simulator with its controller and its own logger (the table clock)."""

    def envelope(self) -> TableEnvelope:
        """Return what the table can do (rates in °/s, accelerations in °/s², log rate in Hz).

        Called before anything moves, so a step outside the envelope is refused at planning
        time (exit 2) rather than faulting the controller mid-run; it must not touch the rig.
        """

    def start(self) -> None:
        """Connect, clear faults, switch the motor on."""

    def move_to(self, inner_deg: float, outer_deg: float) -> None:
        """Position both axes (``inner_deg``, ``outer_deg``, in °) and wait until in position.

        Static and pivoted steps need the table at rest at a known attitude before logging,
        so the call returns only when the controller reports both axes in position.
        """

    def begin_motion(self, step: PlannedStep) -> None:
        """Start the step's motion profile and let it settle for ``step.settle_s``."""

    def record(self, step: PlannedStep) -> SampledLog:
        """Log ``step.samples`` samples, started by the DAQ trigger; return the table log."""

    def end_motion(self) -> None:
        """Bring the table to rest at the step's start position."""

    def safe_stop(self) -> None:
        """Stop motion and switch the motor off; must never raise and be idempotent.

        Called only after :meth:`start` was called (at the end of a run, on a fault, on
        Ctrl-C), never while a procedure is only validated or planned.
        """

    def close(self) -> None:
        """Release the connection; called once at the end of a run, after ``safe_stop``.

        Only ever called after :meth:`start` (also when ``start`` raised); a turntable built
        only to read its :meth:`envelope` (``validate``, ``plan``) is never closed.
        """


def table_capabilities(turntable: object) -> TableCapabilities | None:
    """The turntable's declared capabilities, None when the plugin declares none.

    ``capabilities()`` is optional (older plugins lack it); it must not touch the rig before
    ``start``. A plugin that returns something else is a :class:`PluginError`.
    """
    from aatest.engine.errors import PluginError

    declare = getattr(turntable, "capabilities", None)
    if not callable(declare):
        return None
    declared = declare()
    if not isinstance(declared, TableCapabilities):
        raise PluginError(f"turntable {type(turntable).__name__}.capabilities() returned "
                          f"{type(declared).__name__}, expected TableCapabilities")
    return declared


class TableStatus(BaseModel):
    """One reading of the table's live state (``Turntable.status()``, optional).

    ``time_s`` is when the reading was taken: on the controller's clock when it reports one
    (``clock="controller"``: the Modbus map's controller time, the twin's lab time), else on
    the host's monotonic clock (``clock="host"``). The outer axis is None on a single-axis
    table. A display only: nothing is recorded or judged from it.
    """

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)
    time_s: float
    clock: Literal["controller", "host"]
    inner_position_deg: float
    inner_rate_dps: float
    outer_position_deg: float | None = None
    outer_rate_dps: float | None = None


@runtime_checkable
class StatusTable(Turntable, Protocol):
    """Optional capability of a turntable plugin: report its live position and rate.

    The run polls it while a step runs (about 10 times a second, in a thread of its own) to
    show the operator where the table is; a plugin without it keeps working and the station
    says that this table reports no live status. The call may come while another thread is
    inside :meth:`Turntable.record`: a driver serialises its own link.
    """

    def status(self) -> TableStatus:
        """Read the positions (°) and rates (°/s) now; quick (one request), never moves
        anything. A failed read raises :class:`RigFault`; the run then stops polling and goes
        on (the step's own calls report a dead link)."""


def reports_status(turntable: object) -> bool:
    """True when a turntable plugin offers the optional :class:`StatusTable` capability."""
    return callable(getattr(turntable, "status", None))


def table_status(turntable: object) -> TableStatus | None:
    """The turntable's live status, None when the plugin reports none.

    A plugin whose ``status()`` returns something else is a :class:`PluginError`.
    """
    from aatest.engine.errors import PluginError

    read = getattr(turntable, "status", None)
    if not callable(read):
        return None
    status = read()
    if not isinstance(status, TableStatus):
        raise PluginError(f"turntable {type(turntable).__name__}.status() returned "
                          f"{type(status).__name__}, expected TableStatus")
    return status


def daq_refusal(daq: object, turntable: object) -> str | None:
    """Why ``daq`` cannot record beside ``turntable`` (None: it can, or it does not say).

    A DAQ plugin may define ``cannot_follow(turntable) -> str | None`` (optional): the
    simulated DAQ records the digital twin's sensors and follows only a table that moves that
    twin, so it refuses any other table at ``validate`` instead of failing at the first step.
    """
    check = getattr(daq, "cannot_follow", None)
    return check(turntable) if callable(check) else None


@runtime_checkable
class Daq(Protocol):
    """The on-table sensor logger: its own clock, sensor channels, sync pulse and trigger."""

    def channels(self) -> Sequence[str]:
        """Return the sensor channel names this logger records, in log order.

        The recording and the analyses match channels to the datasheet by these names, so a
        logger wired differently from the datasheet is found before the first step.
        """

    def start(self) -> None:
        """Connect to the logger and check it answers; a logger that does not is a RigFault."""

    def start_logging(self, step: PlannedStep) -> None:
        """Start logging and the trigger (the table log starts on it)."""

    def stop_logging(self) -> SampledLog:
        """Stop logging (a little after the table log ends) and return the DAQ log."""

    def close(self) -> None:
        """Release the logger's bus or connection; called once at the end of a run, and only
        after :meth:`start` was called."""


#: lab seconds of DAQ samples per chunk the runner asks a streaming DAQ for
STREAM_CHUNK_S = 60.0


@runtime_checkable
class StreamingDaq(Daq, Protocol):
    """Optional capability of a DAQ plugin: deliver a long record in chunks as it is logged.

    A plugin that has ``stream_logging`` may record a static step longer than the table's log
    capacity (hours): the runner writes each chunk to the recording as it arrives, so memory is
    one chunk, and the table only logs periodic snapshots meanwhile. Plugins without it keep
    the one-shot ``start_logging``/``stop_logging`` and are refused such steps at planning
    (docs/vendor-plugins.md).
    """

    def stream_logging(self, step: PlannedStep, chunk_s: float) -> Iterator[SampledLog]:
        """Start logging and the trigger, then yield the DAQ log in consecutive chunks of about
        ``chunk_s`` lab seconds (each a :class:`SampledLog` of the same channels, continuing
        the previous one) until the record ends ``stop_lag`` after the table's span; the
        iterator ending is the logger stopping. A fault raises :class:`RigFault`."""


def supports_streaming(daq: object) -> bool:
    """True when a DAQ plugin offers the optional :class:`StreamingDaq` capability."""
    return callable(getattr(daq, "stream_logging", None))


@runtime_checkable
class Chamber(Protocol):
    """A temperature chamber (or none)."""

    def set_temperature(self, setpoint_c: float) -> None:
        """Command the chamber to ``setpoint_c`` (°C) and return without waiting.

        The runner overlaps the ramp with nothing else on purpose: :meth:`wait_stable` is the
        separate call that blocks, so a chamber's own stabilisation criterion stays its own.
        """

    def wait_stable(self, soak_s: float) -> float:
        """Wait for stabilisation plus ``soak_s`` (s); return the sensor temperature (°C)."""

    def off(self) -> None:
        """Switch heating and cooling off (the safe state of a chamber); must never raise."""

    def close(self) -> None:
        """Release the chamber's connection; called once at the end of a run (after
        :meth:`off`), and only when the run got as far as starting the rig."""


R = TypeVar("R")


@dataclass(frozen=True)
class Stability:
    """What a soak until stable achieved: the sensor temperature (°C) when it ended, the
    spread (max − min, °C) of the sensor temperature over the stability window, the window and
    the tolerance asked (s, °C), and the soak time from the set-point command (s)."""

    temperature_c: float
    spread_c: float
    window_s: float
    tolerance_c: float
    waited_s: float

    def as_json(self) -> dict[str, float]:
        """The record kept in the run state and in ``results.metadata.soak_stability``."""
        return {"temperature_c": self.temperature_c, "spread_c": self.spread_c,
                "window_s": self.window_s, "tolerance_c": self.tolerance_c,
                "waited_s": self.waited_s}


@runtime_checkable
class StableChamber(Chamber, Protocol):
    """Optional chamber capability (contract §6): soak until the sensor temperature is stable
    (``soak: {until_stable: {tolerance_c, window_s}, max_s}`` in a procedure)."""

    def wait_until_stable(self, tolerance_c: float, window_s: float, max_s: float) -> Stability:
        """Block until the sensor temperature's spread over the last ``window_s`` s (since the
        set-point command) is at most ``tolerance_c`` °C; raise :class:`RigFault` (exit 3) when it
        is not by ``max_s`` s after the set-point command."""


def soaks_until_stable(chamber: object) -> bool:
    """True when a chamber plugin offers :class:`StableChamber`'s ``wait_until_stable``."""
    return callable(getattr(chamber, "wait_until_stable", None))


class NoOptions(BaseModel):
    """Options of an analysis that takes none."""

    model_config = ConfigDict(extra="forbid", frozen=True)


@dataclass(frozen=True)
class AnalysisOutput(Generic[R]):
    """What one analysis adds: its typed ``result`` (stored under ``results.analysis[key]``)
    and SVG figures for reports.

    A plugin may return a subclass carrying more for its dependants (the ``sync`` analysis adds
    the synchronised steps); only ``result`` and ``figures`` are written to results.json.
    """

    result: R
    figures: Mapping[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class AnalysisContext:
    """What the engine hands one analysis: its validated options and, keyed by analysis key,
    the outputs of the analyses it ``requires`` (and nothing else, so results cannot depend on
    the order analyses are listed in)."""

    options: BaseModel = field(default_factory=NoOptions)
    upstream: Mapping[str, AnalysisOutput[Any]] = field(default_factory=dict)


@runtime_checkable
class Analysis(Protocol):
    """Reads a :class:`Dataset` and returns the typed result stored under
    ``results.analysis[key]``.

    ``requires`` names the analysis *keys* whose outputs it reads from ``context.upstream``
    (the engine runs them first); ``Options`` is a frozen pydantic model with a default for every
    field (extra="forbid"), filled from the procedure's ``analysis: [{name: {options}}]``;
    ``Result`` is the type of ``AnalysisOutput.result`` (a pydantic model).

    An analysis should also declare what it needs and what it judges (:class:`DeclaresNeeds`);
    one without a declaration is not checked by ``validate``.
    """

    key: ClassVar[str]
    requires: ClassVar[tuple[str, ...]]
    Options: ClassVar[type[BaseModel]]
    Result: ClassVar[type[Any]]

    def applies_to(self, data: Dataset) -> bool:
        """False when the data has nothing for this analysis (the engine then skips it)."""

    def run(self, data: Dataset, context: AnalysisContext) -> AnalysisOutput[Any]:
        """Analyse ``data`` with ``context.options`` and the required upstream outputs.

        Returns the typed result (quantities in the units its model's field names state)
        and any SVG figures; it must not read anything but ``data`` and ``context``, so the
        result of a recording is the same whichever other analyses ran.
        """


class DeclaresNeeds(Protocol):
    """The optional part of the analysis contract: what the plan must hold, and what is judged.

    ``requirements`` (:class:`aatest.engine.requirements.Requirement`) are checked against the
    expanded plan by ``aatest validate`` and before ``aatest run`` moves anything: an unmet one
    is refused at the analysis entry's (or the step's) FILE:LINE:COLUMN, exit 2.
    ``judges`` names the acceptance quantities the analysis produces: listed in a procedure,
    each is judged (datasheet limit unless the procedure sets one) or ``not judged``. An
    optional ``produces`` (quantity → requirement) says what the plan needs for one of them.
    docs/interfaces.md lists every built-in analysis' requirements from these declarations.
    """

    requirements: ClassVar[tuple[Requirement, ...]]
    judges: ClassVar[tuple[str, ...]]


@runtime_checkable
class Reporter(Protocol):
    """Renders results into a report file in ``run_dir`` and returns its path."""

    def render(self, results: RunResults, run_dir: Path, template_dir: Path | None) -> Path:
        """Render the typed results into a file in ``run_dir``; return its path.

        ``results`` is the record results.json is written from (read its fields as
        attributes; :mod:`aatest.results.quantities` names each quantity for a person).
        ``template_dir`` is a lab's own template directory (None: the shipped templates). The
        report only presents: verdicts and uncertainties are already in ``results``.
        """


@runtime_checkable
class PdfRenderer(Protocol):
    """Optional capability of a report plugin: print its rendered report as a PDF copy.

    The engine never imports a report module; when ``--pdf`` is asked it checks the loaded
    report plugin for this capability (``isinstance(reporter, PdfRenderer)``) and a report
    without it is refused with exit 2 instead of silently leaving the PDF out.
    """

    def render_pdf(self, report: Path) -> Path:
        """Print ``report`` (the file :meth:`Reporter.render` returned) beside it; return the PDF.

        Raises :class:`~aatest.engine.errors.PluginError` when no PDF can be produced.
        """
