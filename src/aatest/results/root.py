"""``RunResults``: the whole ``results.json`` (docs/interfaces.md §1) as one typed record.

The engine assembles it after the analysis pass; the uncertainty and verdict stages fill in
``verdicts``/``overall`` and the certified fields; the records store allocates the
``certificate_number`` before signing. Files written before the typed record (no
``schema_version``, no verdicts) still load: every later field has a default.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Annotated, Any

from pydantic import BeforeValidator, ConfigDict, Field, model_serializer, model_validator

from aatest.results._fields import Real
from aatest.results.base import Overall, ResultModel, Verdict
from aatest.results.bias import BiasResult
from aatest.results.cross_axis import CrossAxisResult
from aatest.results.frf import FrfResult
from aatest.results.misalignment import MisalignmentResult
from aatest.results.noise import DriftResult, NoiseResult
from aatest.results.reference import ReferenceResult
from aatest.results.scale_factor import ScaleFactorResult
from aatest.results.sensor import UNSTATED, SensorInfo
from aatest.results.sync import SyncResult
from aatest.results.temperature import TemperatureResult
from aatest.results.transfer_function import TransferFunctionResult
from aatest.rig_defaults import LOG_RATE_HZ

#: version of the results.json layout written now; files without the field are version 1
SCHEMA_VERSION = 2


def _third_party_keys(schema: dict[str, Any]) -> None:
    """In the JSON the third-party results sit beside the built-in keys, not under ``extra``."""
    schema["properties"].pop("extra", None)
    schema["additionalProperties"] = True


class AnalysisBlock(ResultModel):
    """``results.analysis``: one optional field per built-in analysis key.

    Results of third-party analyses (entry-point group ``aatest.analyses``) live in ``extra``,
    each validated by its plugin's own ``Result`` model when the plugin runs; in the JSON they
    sit next to the built-in keys, as they always did.
    """

    model_config = ConfigDict(extra="forbid", validate_assignment=True,
                              json_schema_extra=_third_party_keys)

    sync: SyncResult | None = None
    reference: ReferenceResult | None = None
    bias: BiasResult | None = None
    scale_factor: ScaleFactorResult | None = None
    frf: FrfResult | None = None
    transfer_function: TransferFunctionResult | None = None
    temperature: TemperatureResult | None = None
    misalignment: MisalignmentResult | None = None
    noise: NoiseResult | None = None
    drift: DriftResult | None = None
    cross_axis: CrossAxisResult | None = None
    extra: dict[str, Any] = Field(default_factory=dict,
                                  description="key → result of a third-party analysis")

    @model_validator(mode="before")
    @classmethod
    def _collect_extra(cls, data: Any) -> Any:
        """Keys that are not built-in analyses go to ``extra`` (their plugin validates them)."""
        if not isinstance(data, dict):
            return data
        known = set(cls.model_fields)
        extra = dict(data.get("extra") or {})
        extra.update({k: v for k, v in data.items() if k not in known})
        return {k: v for k, v in data.items() if k in known and k != "extra"} | {"extra": extra}

    @model_serializer(mode="wrap")
    def _flatten(self, handler: Any) -> dict[str, Any]:
        """Built-in results that exist, then the third-party ones, all at one level."""
        dumped: dict[str, Any] = handler(self)
        extra = dumped.pop("extra", {}) or {}
        return {k: v for k, v in dumped.items() if v is not None} | extra

    def present(self) -> dict[str, Any]:
        """Key → typed result of every analysis that produced one (built-in and extra)."""
        built_in = {k: getattr(self, k) for k in type(self).model_fields if k != "extra"}
        return {k: v for k, v in built_in.items() if v is not None} | dict(self.extra)


class StepMounting(ResultModel):
    """How the sensor was mounted for a step (misalignment sets name their scenario)."""

    model_config = ConfigDict(extra="allow", validate_assignment=True)
    pivoted: bool = False
    remount: str = "none"
    scenario: str | None = None
    experiment: int | None = None

    @model_serializer(mode="wrap")
    def _without_unset(self, handler: Any) -> dict[str, Any]:
        """A scenario and experiment only where the step has them."""
        dumped: dict[str, Any] = handler(self)
        return {k: v for k, v in dumped.items() if v is not None}


def _extremes_rows(value: Any) -> Any:
    """The step record's ``[least, samples, largest, samples]`` lists as field mappings."""
    if isinstance(value, dict):
        return {k: ChannelExtremes.fields_of(v) if isinstance(v, list | tuple) else v
                for k, v in value.items()}
    return value


class ChannelExtremes(ResultModel):
    """The least and the largest value one sensor channel logged in a step, with the number of
    samples at each (:mod:`aatest.recording.extremes`): a clipped channel holds many samples at
    its logger's rail."""

    least_v: Real = Field(description="least finite value logged, V")
    samples_at_least: int = Field(ge=0, description="samples at exactly that value")
    largest_v: Real = Field(description="largest finite value logged, V")
    samples_at_largest: int = Field(ge=0, description="samples at exactly that value")

    @classmethod
    def fields_of(cls, noted: Sequence[float]) -> dict[str, float]:
        """The fields of ``[least, samples at it, largest, samples at it]``, as the step
        record notes them (:data:`aatest.recording.extremes.Extremes`)."""
        return dict(zip(cls.model_fields, noted, strict=True))


class StepSummary(ResultModel):
    """One recorded step: the planned step (docs/interfaces.md §1 ``steps``) and its samples.

    Fields the plan did not set are absent from the JSON (not ``null``); keys a newer or older
    planner wrote are kept as they are.
    """

    model_config = ConfigDict(extra="allow", validate_assignment=True)
    id: str
    kind: str
    axis: str = "none"
    duration_s: Real = 0.0
    settle_s: Real = 0.0
    sample_rate_hz: Real = LOG_RATE_HZ
    samples: int = 0
    frequency_hz: Real | None = None
    cycles: int | None = None
    amplitude_deg: Real | None = None
    accel_dps2: Real | None = None
    temperature_c: Real | None = None
    group: str | None = None
    repetition: int = 1
    mounting: StepMounting = Field(default_factory=StepMounting)
    table_samples: int | None = None
    daq_samples: int | None = None
    daq_extremes: Annotated[dict[str, ChannelExtremes] | None, BeforeValidator(_extremes_rows)] = (
        Field(None, description="each sensor channel's extremes in the step (absent in results "
              "written before they were kept)"))
    status: str | None = None

    @model_serializer(mode="wrap")
    def _without_unset(self, handler: Any) -> dict[str, Any]:
        """Only what the step stated: a field the plan left empty is not written."""
        dumped: dict[str, Any] = handler(self)
        return {k: v for k, v in dumped.items() if v is not None}


class InstrumentTrace(ResultModel):
    """Calibration certificate of one rig instrument, as the rig description states it."""

    cert_id: str
    cert_date: str
    lab: str
    accuracy: str


class ReferenceTraceability(ResultModel):
    """The reference's traceability the uncertainty stage used (``metadata.traceability``)."""

    stated: bool = Field(description="the rig description stated its instruments")
    instruments: dict[str, InstrumentTrace] = Field(default_factory=dict)
    reference_temperature_c: Real


class UnitRef(ResultModel):
    """The calibrated unit as the procedure names it (``metadata.sensor``)."""

    model_config = ConfigDict(extra="allow", validate_assignment=True)
    model: str | None = None
    serial: str | None = None


class PromptAnswer(ResultModel):
    """Who confirmed an operator prompt, when and through which channel."""

    model_config = ConfigDict(extra="allow", validate_assignment=True)
    step_id: str | None = None
    answered_by: str | None = None
    answered_utc: str | None = None
    via: str | None = None


def _sensor_records(value: Any) -> Any:
    """Sensor records of any version: keys this version does not know are ignored."""
    if isinstance(value, list):
        return [SensorInfo.from_metadata(v) if isinstance(v, dict) else v for v in value]
    return value


class RunMetadata(ResultModel):
    """``results.metadata``: the run's metadata as recorded, with the parts the engine reads
    typed (the sensors, the report template, the reference's traceability); every other key
    of the recording's metadata is kept as it is."""

    model_config = ConfigDict(extra="allow", validate_assignment=True)
    sensors: Annotated[list[SensorInfo], BeforeValidator(_sensor_records)] = Field(
        default_factory=list, description="one record per sensor channel")
    sensor: UnitRef | None = Field(None, description="the unit: sensor model and serial")
    procedure: str | None = None
    standard: str | None = None
    procedure_sha256: str | None = None
    started_utc: str | None = Field(None, description="when the run started, ISO 8601")
    operator: str | None = None
    recording: str | None = Field(None, description="the recording the results are from")
    table_serial: str | None = None
    report_template: str | None = None
    plugin_versions: dict[str, str] = Field(default_factory=dict)
    prompt_answers: list[PromptAnswer] = Field(default_factory=list)
    lab: dict[str, Any] | None = Field(None, description="the issuing lab's identity")
    adjustment: dict[str, Any] | None = Field(None, description="as-found/as-left, if made")
    traceability: ReferenceTraceability | None = None

    @model_serializer(mode="wrap")
    def _without_unset(self, handler: Any) -> dict[str, Any]:
        """Keys the run did not record are not written (as before the metadata was typed)."""
        dumped: dict[str, Any] = handler(self)
        return {k: v for k, v in dumped.items()
                if k in self.model_fields_set or k in (self.model_extra or {})}

    def unit(self) -> UnitRef:
        """The calibrated unit: ``sensor`` as the procedure named it; else, per field, the
        model and the serial that every channel's sensor record states alike (imported data
        names its unit only per channel, in ``dataset.yaml`` or ``mapping.yaml``); a field
        no record states, or that they state differently, stays None."""
        if self.sensor is not None:
            return self.sensor

        def common(values: set[str]) -> str | None:
            values -= {UNSTATED}
            return values.pop() if len(values) == 1 else None

        return UnitRef(model=common({s.model for s in self.sensors}),
                       serial=common({s.serial for s in self.sensors}))

    def sensor_of(self, channel: str) -> SensorInfo:
        """The channel's sensor record, else the reference sensor's datasheet nominals."""
        return next((s for s in self.sensors if s.channel == channel),
                    SensorInfo(channel=channel or "unnamed"))

    def recorded(self, key: str) -> Any:
        """A metadata key this model does not type (None when the run did not record it)."""
        return (self.model_extra or {}).get(key)


class Signature(ResultModel):
    """Which key signed the bundle (the signature itself is a file next to the report)."""

    fingerprint: str


class LoggedTemperature(ResultModel):
    """Min, mean and max of every temperature sample the loggers recorded (°C), for the
    certificate's environmental conditions (ISO/IEC 17025 §7.8.4.1 a); computed when the run is
    analysed, so a report never reads the recording."""

    min_c: Real | None = Field(None, description="lowest logged temperature, °C")
    mean_c: Real | None = Field(None, description="mean of all logged temperature samples, °C")
    max_c: Real | None = Field(None, description="highest logged temperature, °C")
    samples: int = Field(0, description="temperature samples summarised (0: none logged)")
    source: str = Field("", description="the recording or import directory they were read from")


class RunResults(ResultModel):
    """The document between analysis and report: what was run, measured and decided."""

    schema_version: int = Field(1, description="results.json layout version")
    procedure: str
    rig: dict[str, Any] = Field(default_factory=dict, description="rig plugins and options")
    steps: list[StepSummary] = Field(default_factory=list,
                                     description="each planned step plus sample counts")
    analysis: AnalysisBlock = Field(default_factory=AnalysisBlock)
    analysis_errors: dict[str, str] = Field(default_factory=dict)
    analysis_skipped: list[str] = Field(default_factory=list)
    lab_duration_s: Real = 0.0
    wall_duration_s: Real = 0.0
    metadata: RunMetadata = Field(default_factory=RunMetadata)
    figures: dict[str, dict[str, str]] = Field(default_factory=dict,
                                               description="analysis key → name → SVG")
    verdicts: list[Verdict] = Field(default_factory=list)
    overall: Overall = "none"
    certificate_number: str | None = None
    signature: Signature | None = None
    logged_temperature: LoggedTemperature | None = Field(
        None, description="the temperatures logged during the run (absent: analysed before "
                          "this field existed)")

    def steps_of_kind(self, kind: str) -> list[StepSummary]:
        """The recorded steps of one kind (``static``, ``sine``, ``constant_rate``, …)."""
        return [s for s in self.steps if s.kind == kind]

    def sensor(self, channel: str) -> SensorInfo:
        """The channel's sensor record (the reference sensor's nominals when not recorded)."""
        return self.metadata.sensor_of(channel)
