"""The procedure YAML as typed, frozen models (docs/interfaces.md §2; the JSON Schema made from
them is the contract).

A procedure says *what* to do: the device under test, the rig plugins, the sampling, a list of
steps and step *generators*, the analyses and the report. Every step entry is a mapping with
exactly one key naming its kind (``static``, ``sine``, ``sine_sweep``, ``constant_rate``,
``coordinated_rates``, ``multi_position``, ``temperature_steps``, ``repeat``, ``misalignment``,
``operator``). :func:`aatest.engine.procedure.planner.expand` turns them into concrete steps.

Numbers are strict: a string is never silently read as a number, ``.nan``/``.inf`` are
rejected, unknown keys are errors. Units: degrees, seconds, °/s, °/s², °C, Hz.

Example
-------
>>> from aatest.engine.procedure.models import Procedure
>>> proc = Procedure.model_validate({
...     "procedure": "demo", "sensor": {"model": "sr207"},
...     "steps": [{"sine": {"axis": "inner", "frequency_hz": 1.0, "accel_dps2": 400}}]})
>>> proc.sampling.samples, proc.steps[0].sine.snap
(131072, 'coherent')
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    PrivateAttr,
    Strict,
    StrictBool,
    StrictStr,
    model_validator,
)

from aatest.rig_defaults import LOG_RATE_HZ, RECORD_SAMPLES

# --- strict scalar types (YAML "5" must not become 5, true must not become 1) -----------------
Float = Annotated[float, Strict()]
PositiveFloat = Annotated[float, Strict(), Field(gt=0)]
NonNegFloat = Annotated[float, Strict(), Field(ge=0)]
PositiveInt = Annotated[int, Strict(), Field(gt=0)]
Name = Annotated[str, Strict(), Field(min_length=1, max_length=200)]
TableAxis = Literal["inner", "outer"]
SnapMode = Literal["coherent", "none"]
Scenario = Literal["A", "B", "C", "D", "E", "F", "G", "H"]
Mount = Literal["original", "pivoted"]


def _non_empty(value: tuple[Any, ...]) -> tuple[Any, ...]:
    # checked after the items (pydantic's min_length would add a spurious error when an item fails)
    if not value:
        raise ValueError("must have at least one item")
    return value


NonEmpty = (AfterValidator(_non_empty), Field(json_schema_extra={"minItems": 1}))

#: a cap on generated counts so a typo cannot plan a million steps
MAX_COUNT = 1000


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class Overrides(_Strict):
    """Per-step overrides of the procedure's ``sampling`` block."""

    samples: PositiveInt | None = Field(None, description="record length in samples")
    duration_s: PositiveFloat | None = Field(
        None, description="record length in seconds (alternative to samples: round(duration·rate))")
    settle_s: NonNegFloat | None = Field(None, description="time in motion before recording")

    @model_validator(mode="after")
    def _one_length(self) -> Overrides:
        if self.samples is not None and self.duration_s is not None:
            raise ValueError("give either samples or duration_s, not both")
        return self


class Placed(Overrides):
    """A step that starts from a table orientation."""

    inner_deg: Float = Field(0.0, description="inner-axis start position")
    outer_deg: Float = Field(0.0, description="outer-axis start position")


class StaticStep(Placed):
    """Table still at (inner_deg, outer_deg); records bias/noise."""

    motor_on: StrictBool = True
    label: Name | None = None


class SineStep(Placed):
    """One sinusoidal position profile θ = A·sin(2πft) on one axis.

    Give ``frequency_hz`` (snapped to whole cycles in the record when ``snap: coherent``) or
    ``cycles`` (f = cycles·rate/samples exactly), and exactly one of ``accel_dps2`` (peak
    acceleration; A = α/(2πf)²) or ``amplitude_deg``.
    """

    axis: TableAxis = "inner"
    frequency_hz: PositiveFloat | None = None
    cycles: PositiveInt | None = None
    accel_dps2: PositiveFloat | None = None
    amplitude_deg: PositiveFloat | None = None
    snap: SnapMode = "coherent"

    @model_validator(mode="after")
    def _exactly_one(self) -> SineStep:
        if (self.frequency_hz is None) == (self.cycles is None):
            raise ValueError("give exactly one of frequency_hz or cycles")
        if (self.accel_dps2 is None) == (self.amplitude_deg is None):
            raise ValueError("give exactly one of accel_dps2 or amplitude_deg")
        return self


class SweepFrequencies(_Strict):
    """Frequency grid of a sweep.

    Grid rule: ``start_hz·ratio^k`` for every k with the value ≤ ``stop_hz``, plus ``stop_hz``
    itself (the terminal frequency), plus ``include``. With ``snap: coherent`` each point is
    moved to f = c·Fs/N with c = round(f·N/Fs) (nearest integer, halves up, at least 1) and
    duplicates are merged. ``cycles`` lists the integer cycle counts explicitly; when given it
    defines the grid exactly (the other keys are then only a record of where the counts came
    from) — this is how a published matrix that departs from nearest rounding is reproduced.
    """

    start_hz: PositiveFloat | None = None
    ratio: Annotated[float, Strict(), Field(gt=1.0)] | None = None
    stop_hz: PositiveFloat | None = None
    include: tuple[PositiveFloat, ...] = ()
    snap: SnapMode = "coherent"
    cycles: tuple[PositiveInt, ...] | None = Field(
        None, description="explicit whole-cycle counts; define the grid exactly")

    @model_validator(mode="after")
    def _grid(self) -> SweepFrequencies:
        geometric = (self.start_hz, self.ratio, self.stop_hz)
        if any(v is not None for v in geometric) and any(v is None for v in geometric):
            raise ValueError("a geometric grid needs start_hz, ratio and stop_hz together")
        if self.start_hz is not None and self.stop_hz is not None and self.stop_hz < self.start_hz:
            raise ValueError("stop_hz must not be below start_hz")
        if self.start_hz is None and not self.include and not self.cycles:
            raise ValueError("give a geometric grid, include points or cycles")
        if self.cycles is not None and self.snap != "coherent":
            raise ValueError("explicit cycles imply snap: coherent")
        return self


class SineSweep(Placed):
    """Stepped sines over a frequency grid, one group per acceleration and per amplitude.

    ``accelerations_dps2`` are constant-acceleration groups (A = α/(2πf)²),
    ``amplitudes_deg`` constant-position groups (α = A·(2πf)²). With
    ``skip_outside_envelope: true`` points beyond the table limits, the sensor test ceiling or
    floor are dropped and listed as skipped; by default (false) they make the plan invalid.
    """

    axis: TableAxis = "inner"
    frequencies: SweepFrequencies
    accelerations_dps2: tuple[PositiveFloat, ...] = ()
    amplitudes_deg: tuple[PositiveFloat, ...] = ()
    skip_outside_envelope: StrictBool = False

    @model_validator(mode="after")
    def _groups(self) -> SineSweep:
        if not self.accelerations_dps2 and not self.amplitudes_deg:
            raise ValueError("give accelerations_dps2 and/or amplitudes_deg")
        return self


class ConstantRate(Placed):
    """One record per rate at constant rate on one axis (sign gives the direction)."""

    axis: TableAxis = "inner"
    rates_dps: Annotated[tuple[Float, ...], *NonEmpty]


class CoordinatedRates(Placed):
    """Two-axis constant rates (docs/method.md §3): inner at ω_i = 2πf, outer at ω_o = α/ω_i.

    A sensor perpendicular to the inner axis then sees α(t) = −ω_i·ω_o·sin(ω_i t). With
    ``snap: coherent`` f is snapped so the record holds whole inner revolutions.
    """

    frequencies_hz: Annotated[tuple[PositiveFloat, ...], *NonEmpty]
    accelerations_dps2: Annotated[tuple[PositiveFloat, ...], *NonEmpty]
    snap: SnapMode = "coherent"


class MultiPosition(Overrides):
    """Static positions (docs/method.md §4.1), repeated, in original and pivoted mounting."""

    positions: Annotated[tuple[tuple[Float, Float], ...], *NonEmpty] = Field(
        description="list of [inner_deg, outer_deg]")
    repetitions: Annotated[int, Strict(), Field(ge=1, le=100)] = 3
    mountings: Annotated[tuple[Mount, ...], *NonEmpty] = ("original", "pivoted")
    original_prompt: Name = "Mount the sensor unit in its original orientation."
    pivoted_prompt: Name = "Pivot every sensor 180° about its sensitive axis and re-mount the unit."
    motor_on: StrictBool = True


class DynamicSine(_Strict):
    """The sine record taken at each temperature (dynamic temperature test)."""

    axis: TableAxis = "inner"
    frequency_hz: PositiveFloat = 1.0
    accel_dps2: PositiveFloat = 400.0
    snap: SnapMode = "coherent"
    settle_s: NonNegFloat | None = None


class UntilStable(_Strict):
    """Stable: the sensor temperature's spread (max − min) over the last ``window_s`` seconds
    is at most ``tolerance_c`` °C."""

    tolerance_c: PositiveFloat = Field(description="largest spread over the window, °C")
    window_s: PositiveFloat = Field(description="the trailing window the spread is taken over, s")


class Soak(_Strict):
    """Soak until the sensor temperature is stable, at most ``max_s`` seconds (a chamber that
    is not stable by then is a rig fault, exit 3; the run can be resumed)."""

    until_stable: UntilStable
    max_s: PositiveFloat = Field(description="longest soak, s (the plan's lab time counts it)")

    @model_validator(mode="after")
    def _window_fits(self) -> Soak:
        if self.max_s < self.until_stable.window_s:
            raise ValueError(f"max_s ({self.max_s:g} s) is shorter than the stability window "
                             f"until_stable.window_s ({self.until_stable.window_s:g} s)")
        return self


class TemperatureSteps(Overrides):
    """Chamber set-points (docs/method.md §4.2): soak, switch off, wait, record.

    The wait after switching the chamber off is the static record's settling time; with
    ``dynamic`` a sine record follows the static one at every set-point.
    """

    setpoints_c: Annotated[tuple[Annotated[float, Strict(), Field(ge=-80, le=200)], ...], *NonEmpty]
    soak_s: NonNegFloat = 900.0
    soak: Soak | None = Field(None, description="soak until stable instead of a fixed soak_s: "
                              "{until_stable: {tolerance_c, window_s}, max_s}")
    off_wait_s: NonNegFloat = 60.0
    static: StrictBool = True
    bias_pair: StrictBool = Field(
        False, description="also record the static position with the outer axis turned 180° "
        "(the sensitive axis down): a ±1 g pair, so the bias is measured at every set-point")
    inner_deg: Float = 0.0
    outer_deg: Float = 0.0
    dynamic: DynamicSine | None = None

    @model_validator(mode="after")
    def _records(self) -> TemperatureSteps:
        if not self.static and self.dynamic is None:
            raise ValueError("a temperature step needs a static and/or a dynamic record")
        if self.soak is not None and "soak_s" in self.model_fields_set:
            raise ValueError("give soak_s (a fixed soak) or soak (until stable), not both")
        return self


class Misalignment(Overrides):
    """Pivoted misalignment test of a three-sensor unit (docs/method.md §4.5).

    Sets A, C, E, G run experiments 1–3 in original mounting, B, D, F, H experiments 4–6 with
    every sensor pivoted 180°; A/B record sequentially, C/D re-mount the sensors, E/F the
    block, G/H both, before every repetition. Experiments: 1/4 excite I, 2/5 excite O, 3/6
    rotate inner 90° and excite O.
    """

    scenarios: Annotated[tuple[Scenario, ...], *NonEmpty] = ("A", "B", "C", "D", "E", "F", "G", "H")
    experiments: Annotated[tuple[Annotated[int, Strict(), Field(ge=1, le=6)], ...], *NonEmpty] = (
        1, 2, 3, 4, 5, 6)
    repetitions: Annotated[int, Strict(), Field(ge=1, le=100)] = 3
    frequency_hz: PositiveFloat = 1.0
    accel_dps2: PositiveFloat = 100.0
    snap: SnapMode = "coherent"


class Repeat(_Strict):
    """Run the nested steps ``count`` times (repetition numbers 1..count)."""

    count: Annotated[int, Strict(), Field(ge=1, le=MAX_COUNT)]
    steps: Annotated[tuple[StepEntry, ...], *NonEmpty]


class Operator(_Strict):
    """An instruction shown to the operator before the next step runs."""

    prompt: Name


STEP_KINDS: tuple[str, ...] = ("static", "sine", "sine_sweep", "constant_rate",
                               "coordinated_rates", "multi_position", "temperature_steps",
                               "repeat", "misalignment", "operator")


class StepEntry(_Strict):
    """One entry of ``steps``: a mapping with exactly one key naming the step kind."""

    model_config = ConfigDict(json_schema_extra={"minProperties": 1, "maxProperties": 1})

    static: StaticStep | None = None
    sine: SineStep | None = None
    sine_sweep: SineSweep | None = None
    constant_rate: ConstantRate | None = None
    coordinated_rates: CoordinatedRates | None = None
    multi_position: MultiPosition | None = None
    temperature_steps: TemperatureSteps | None = None
    repeat: Repeat | None = None
    misalignment: Misalignment | None = None
    operator: Operator | None = None

    @model_validator(mode="before")
    @classmethod
    def _empty_means_defaults(cls, data: Any) -> Any:
        """``- static:`` (no value) means a step with all defaults."""
        if isinstance(data, dict) and "static" in data and data["static"] is None:
            return {**data, "static": {}}
        return data

    @model_validator(mode="after")
    def _single_key(self) -> StepEntry:
        given = [k for k in STEP_KINDS if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError(f"a step needs exactly one of {', '.join(STEP_KINDS)}; got "
                             f"{', '.join(given) or 'none'}")
        return self

    @property
    def kind(self) -> str:
        """The name of the one key this entry carries."""
        return next(k for k in STEP_KINDS if getattr(self, k) is not None)

    @property
    def body(self) -> BaseModel:
        """The step or generator model under that key."""
        return getattr(self, self.kind)  # type: ignore[no-any-return]


Repeat.model_rebuild()


class SensorSpec(_Strict):
    """Device under test, resolved through the ``aatest.sensors`` plugins."""

    model_config = ConfigDict(coerce_numbers_to_str=True)
    model: Name
    serial: Annotated[str, Field(min_length=1, max_length=200)] = "unknown"  # 1234 → "1234"


class RigPlugins(_Strict):
    """Plugin names per kind; ``--rig RIG.yaml`` overrides them with options."""

    turntable: Name = "sim"
    daq: Name = "sim"
    chamber: Name = "none"


class Sampling(_Strict):
    """Default logging for every record (2 kHz, 2^17 samples, 5 s settling)."""

    rate_hz: PositiveFloat = LOG_RATE_HZ
    samples: PositiveInt = RECORD_SAMPLES
    settle_s: NonNegFloat = 5.0


class ReportOptions(_Strict):
    """Which report plugin renders the results, and whether to sign them."""

    template: Name = "calibration-certificate"
    sign: StrictBool = False


#: one ``analysis:`` entry: a plugin name (or alias) or ``{name: {options}}``
AnalysisEntry = Annotated[
    Name | Annotated[dict[Name, dict[str, Any]], Field(min_length=1, max_length=1)],
    Field(description="an analysis name, or a mapping {name: {options}} with one key"),
]

DecisionRule = Literal["simple", "guarded", "shared-risk"]


class AcceptanceLimits(_Strict):
    """Acceptance limits on |value|, each overriding the sensor datasheet's (docs/method.md §1.3).

    Units are in the names; an unset limit comes from the sensor plugin's datasheet.
    """

    scale_factor_deviation_pct: PositiveFloat | None = Field(
        None, description="|K/K_nominal − 1| in %")
    bias_deviation_v: PositiveFloat | None = Field(None, description="|bias − nominal bias| in V")
    nonlinearity_pct_fr: PositiveFloat | None = Field(None, description="in % of full range")
    g_sensitivity_dps2_per_g: PositiveFloat | None = Field(None, description="in (°/s²)/g")
    cross_axis_ratio: PositiveFloat | None = Field(None, description="worst x/y ratio (1 = 100 %)")
    misalignment_deg: PositiveFloat | None = Field(None, description="pivoted-method angle")
    bias_temperature_v_per_c: PositiveFloat | None = Field(None, description="in V/°C")
    scale_temperature_per_c: PositiveFloat | None = Field(None, description="relative, in 1/°C")
    noise_rms_v: PositiveFloat | None = Field(None, description="worst step's output noise, V RMS")


#: the acceptance quantities (the limit names of :class:`AcceptanceLimits`)
JudgedQuantity = Literal["scale_factor_deviation_pct", "bias_deviation_v", "nonlinearity_pct_fr",
                         "g_sensitivity_dps2_per_g", "cross_axis_ratio", "misalignment_deg",
                         "bias_temperature_v_per_c", "scale_temperature_per_c", "noise_rms_v"]


class Acceptance(_Strict):
    """How results are judged: the ILAC-G8 decision rule and limits overriding the datasheet.

    ``simple``: pass iff |value| ≤ limit; ``guarded``: the guard band is the expanded
    uncertainty U (pass iff |value| + U ≤ limit, fail iff |value| − U > limit, otherwise
    conditional); ``shared-risk``: as simple, a verdict within U of the limit is conditional.
    """

    rule: DecisionRule = "simple"
    limits: AcceptanceLimits = AcceptanceLimits()
    judge: tuple[JudgedQuantity, ...] | None = Field(
        None, description="the quantities judged (default: every limit the procedure sets and "
        "every quantity its listed analyses produce); one that no listed analysis produces is "
        "refused before the run, one the data do not give is 'not judged' and the overall "
        "verdict 'incomplete'")


class Procedure(_Strict):
    """A test procedure: the root of the procedure YAML."""

    procedure: Name = Field(description="procedure name, used in run directories and reports")
    standard: StrictStr = "IEEE-671-style"
    description: StrictStr = ""
    sensor: SensorSpec
    rig: RigPlugins = RigPlugins()
    sampling: Sampling = Sampling()
    steps: Annotated[tuple[StepEntry, ...], *NonEmpty]
    analysis: tuple[AnalysisEntry, ...] = Field(
        (), description="analyses to run: a name, or {name: {options}} (options are checked "
        "against the analysis plugin's own Options model when the procedure is loaded)")
    acceptance: Acceptance = Acceptance()
    report: ReportOptions = ReportOptions()

    # where the procedure came from (set by the loader; used to locate planning problems)
    _source_file: str | None = PrivateAttr(None)
    _tree: Any = PrivateAttr(None)

    @model_validator(mode="after")
    def _prompt_has_step(self) -> Procedure:
        if self.steps[-1].operator is not None:
            raise ValueError("the last step is an operator prompt with no step to attach it to")
        return self

    @property
    def source_file(self) -> str | None:
        """The YAML file this procedure was loaded from, if any."""
        return self._source_file

    @property
    def source_tree(self) -> Any:
        """The position-tracking YAML tree (ruamel round-trip nodes), if loaded from a file."""
        return self._tree

    def with_source(self, filename: str, tree: Any) -> Procedure:
        """Record the source file and YAML tree (called by the loader)."""
        self._source_file = filename
        self._tree = tree
        return self
