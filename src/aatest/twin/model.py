"""The rig/sensor model YAML the twin loads and ``aatest diagnose --model-out`` writes.

Every error term is one named effect of the contract vocabulary (docs/interfaces.md §4), with the
same parameter names, so a diagnosed effect drops straight into the model. An effect is on
when its field is present (not ``None``). Units: degrees, seconds, volts, °C.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from aatest.engine.datasheet import (
    REFERENCE_BIAS_V,
    REFERENCE_RANGE_DPS2,
    REFERENCE_SCALE_V_PER_DPS2,
)
from aatest.rig_defaults import (
    INNER_ACCEL_DPS2,
    INNER_RATE_DPS,
    LOG_CAPACITY_SAMPLES,
    LOG_RATE_HZ,
    OUTER_ACCEL_DPS2,
    OUTER_RATE_DPS,
)

if TYPE_CHECKING:
    from aatest.engine.rig_description import Instruments, LoggerSpec


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid")


# --- the effect vocabulary (names and parameters are part of the public contract) -------------


class BiasTemperature(_Model):
    """bias = b0 + c·(T − T_ref)."""

    coefficient_v_per_c: float


class ScaleTemperature(_Model):
    """scale = K·(1 + c·(T − T_ref))."""

    coefficient_per_c: float


class NonlinearityCubic(_Model):
    """output = b0 + K·α·(1 + c3·(α/α_range)²)."""

    c3: float


class Saturation(_Model):
    """The sensed acceleration clips at ±limit."""

    limit_dps2: float = Field(gt=0)


class Hysteresis(_Model):
    """Sensed α follows a play (backlash) operator of this half width."""

    half_width_dps2: float = Field(ge=0)


class SensorDynamics(_Model):
    """H(s) = ωn²/(s² + 2ζωn·s + ωn²)."""

    natural_frequency_hz: float = Field(gt=0)
    damping: float = Field(gt=0)


class AmplitudeDamping(_Model):
    """The fluid rotor's damping ratio depends on the acceleration amplitude A:
    ζ(A) = ζ + ``damping_per_decade``·log10(A/``reference_dps2``), ζ the ``sensor_dynamics``
    damping (reached at ``reference_dps2``), A = √2·RMS over the trailing ``window_s`` of the
    sensed acceleration within the excitation band (4th-order low-pass at ``band_hz``: the
    35 Hz motor band is not the rotor's excitation). Negative per-decade values (the measured
    case, docs/method.md §1.3) damp small motions more: the gain at 10 Hz falls 1.0 dB at
    1 °/s² but 0.2 dB at 400 °/s², and the phase delay grows at low acceleration."""

    damping_per_decade: float
    reference_dps2: float = Field(gt=0)
    window_s: float = Field(2.5, gt=0, description="≥ one period of the slowest sine")
    band_hz: float = Field(15.0, gt=0, description="the amplitude's band (low-pass corner)")
    floor_dps2: float | None = Field(
        None, gt=0, description="below this amplitude ζ stays at ζ(floor) (None: no floor)")


class TimeDelay(_Model):
    """Pure transport delay; the output lags the motion."""

    delay_s: float = Field(ge=0)


class ClockDrift(_Model):
    """t_table = t0 + t_daq·(1 + drift_ppm·1e-6); DAQ slower → positive."""

    drift_ppm: float


class JerkSensitivity(_Model):
    """Output term c·dα/dt."""

    coefficient_v_per_dps3: float


class GSensitivity(_Model):
    """Sensed α += c·(specific force along the sensor axis in g)."""

    coefficient_dps2_per_g: float


class CrossAxis(_Model):
    """Response to acceleration about the sensor's x / y axis, relative to z."""

    ratio_x: float = 0.0
    ratio_y: float = 0.0


class Misalignment(_Model):
    """Input axis tilted by ``angle_deg`` from the reference axis, towards ``azimuth_deg``
    (0° = towards the sensor's x axis, 90° = towards y)."""

    angle_deg: float
    azimuth_deg: float = 0.0


class RateRipple(_Model):
    """Position-periodic table error θ = θ_cmd + a·sin(2π·n·θ_cmd + φ)."""

    cycles_per_deg: float = Field(gt=0)
    amplitude_deg: float
    phase_rad: float = 0.0
    rejection_bandwidth_hz: float | None = Field(
        None, gt=0, description="None: the contract formula exactly. Else the ripple is a "
        "position-periodic disturbance the servo rejects: the real amplitude at ripple "
        "frequency f = n·|rate| is a·|S(f)|, S = x³/(1+x)³, x = jf/f_b (why 10 °/s shows "
        "mainly the 2 cycles/° line, docs/method.md §1.2)")


class MotorVibration(_Model):
    """Narrow-band axis acceleration A·sin(2πft + φ) while the motor is on (A is the peak)."""

    frequency_hz: float = Field(gt=0)
    amplitude_dps2: float = Field(ge=0)
    phase_rad: float = 0.0
    bandwidth_hz: float = Field(0.0, ge=0, description="0: a pure tone; >0: a narrow band")


class BiasDrift(_Model):
    """Slow bias wander of a sensor at rest (docs/method.md §1.3, long static test), in volts.

    bias(t) += rate·t + random walk (increments N(0, K²·dt): rate random walk in the Allan
    reading, slope +½) + a first-order Gauss–Markov process of RMS ``instability_v`` and
    correlation time ``correlation_s`` (the flat bias-instability region). Not a diagnose effect.
    """

    rate_v_per_h: float = 0.0
    random_walk_v_per_sqrt_s: float = Field(0.0, ge=0)
    instability_v: float = Field(0.0, ge=0)
    correlation_s: float = Field(100.0, gt=0)


class EncoderError(_Model):
    """The encoder's angle error (what its accuracy bounds): the logged angle is
    θ + a1·sin(θ + φ1) + an·sin(n·θ + φn); the table itself moves to the true angle."""

    once_per_rev_deg: float = 0.0
    once_per_rev_phase_rad: float = 0.0
    harmonic_deg: float = 0.0
    harmonic_cycles_per_rev: int = Field(1, ge=1)
    harmonic_phase_rad: float = 0.0

    def error_deg(self, angle_deg: Any) -> Any:
        """The error added to the logged angle at ``angle_deg`` (deg, array or float)."""
        theta = np.radians(angle_deg)
        return (self.once_per_rev_deg * np.sin(theta + self.once_per_rev_phase_rad)
                + self.harmonic_deg * np.sin(self.harmonic_cycles_per_rev * theta
                                             + self.harmonic_phase_rad))


class LoggerError(_Model):
    """The sensor logger's own error (what its calibration certificate bounds):
    logged = (1 + gain_error)·V + offset_v."""

    gain_error: float = 0.0
    offset_v: float = 0.0
    timing_offset_s: float = Field(0.0, description="the logger samples this much late "
                                   "against the table's latch (not seen by the sync fit)")


class JerkDistortion(_Model):
    """Second-order distortion of the rotor's response: output += c·(dα_r/dt)², α_r the
    acceleration after ``sensor_dynamics`` (the sensed acceleration without them).

    For a sine of amplitude A at frequency f the term is c·(2πf·A)²·cos²: a second harmonic of
    relative size c·(2πf)²·A/(2K) and a DC shift, nothing at the fundamental — the FRF is
    unchanged while the total harmonic distortion rises with f² and with A (the measured THD
    rises above ≈ 4 Hz and with amplitude, docs/method.md §1.3), and no linear model of the
    table's estimate can fit it. Motion above the rotor's response (the table's 35 Hz motor
    band, its 60–130 Hz ripple) is filtered by the dynamics before it is squared.
    """

    coefficient_v_per_dps3_squared: float


class ExcessNoise(_Model):
    """Extra white output noise (e.g. through a slip ring)."""

    rms_v: float = Field(ge=0)


class RotorStiction(_Model):
    """The rotor sticks to the case around every rate reversal: while the case's angular rate
    about the sensor axis is within ±``breakaway_rate_dps`` of zero the sensor loses the share
    ``depth`` of its response, outside it responds fully. On a sine of acceleration A at f the gap
    removes the acceleration peaks (rate zero) and costs ≈ 8·depth·r·f/A of the fundamental
    with no phase shift, r the break-away rate: a loss growing linearly with frequency at
    constant acceleration and vanishing at large A (docs/method.md §1.3: at 1 and 10 °/s² the
    gain starts to fall at ≈ 2 Hz). The table's own vibration dithers the gap at very low
    acceleration, which bounds the loss there."""

    breakaway_rate_dps: float = Field(gt=0)
    depth: float = Field(1.0, gt=0, le=1, description="the share of the response lost while "
                         "the rotor sticks (1: none left)")


#: effect name → parameter model, exactly the contract vocabulary
EFFECTS: dict[str, type[_Model]] = {
    "bias_temperature": BiasTemperature,
    "scale_temperature": ScaleTemperature,
    "nonlinearity_cubic": NonlinearityCubic,
    "saturation": Saturation,
    "hysteresis": Hysteresis,
    "sensor_dynamics": SensorDynamics,
    "amplitude_damping": AmplitudeDamping,
    "time_delay": TimeDelay,
    "clock_drift": ClockDrift,
    "jerk_sensitivity": JerkSensitivity,
    "g_sensitivity": GSensitivity,
    "cross_axis": CrossAxis,
    "misalignment": Misalignment,
    "rate_ripple": RateRipple,
    "motor_vibration": MotorVibration,
    "excess_noise": ExcessNoise,
    "rotor_stiction": RotorStiction,
    "jerk_distortion": JerkDistortion,
}

class PluginEffect(_Model):
    """An effect from an installed plugin (entry-point group ``aatest.effects``).

    ``distribution`` names the package that provides it, so a model that needs a missing
    plugin says what to install. Checked when the model is built or loaded: the effect must be
    installed and ``parameters`` must be exactly its parameters (shape ones within bounds).
    """

    effect: str
    distribution: str | None = None
    parameters: dict[str, float]

    @model_validator(mode="after")
    def _installed(self) -> PluginEffect:
        from aatest.effects import load_effect
        from aatest.engine.errors import PluginError

        try:
            eff = load_effect(self.effect, self.distribution).effect
        except PluginError as exc:  # located by the loader: FILE:LINE: field: this message
            raise ValueError(str(exc)) from exc
        declared = [p.name for p in (*eff.parameters, *eff.shape_parameters)]
        if sorted(declared) != sorted(self.parameters):
            raise ValueError(f"effect {self.effect!r} takes parameters {', '.join(declared)}, "
                             f"not {', '.join(self.parameters) or 'none'}")
        for p in eff.shape_parameters:
            value = self.parameters[p.name]
            below = p.lower is not None and value < p.lower
            if below or (p.upper is not None and value > p.upper):
                raise ValueError(f"{self.effect}.{p.name} = {value:g} {p.unit} is outside "
                                 f"[{p.lower:g}, {p.upper:g}]")
        return self


# --- the rig parts ------------------------------------------------------------------------------


class SensorModel(_Model):
    """One sensor channel: nominal terms plus any switched-on effects.

    Bias, scale factor and range default to the reference sensor's datasheet
    (:mod:`aatest.engine.datasheet`).
    """

    channel: str = "v_sz"
    axis: Literal["I", "O", "P"] = "I"
    bias_v: float = REFERENCE_BIAS_V
    scale_v_per_dps2: float = REFERENCE_SCALE_V_PER_DPS2
    range_dps2: float = REFERENCE_RANGE_DPS2
    noise_rms_v: float = Field(0.001, ge=0)
    resolution_dps2: float = Field(0.0, ge=0, description="threshold/resolution (0 = ideal)")
    bias_temperature: BiasTemperature | None = None
    scale_temperature: ScaleTemperature | None = None
    nonlinearity_cubic: NonlinearityCubic | None = None
    saturation: Saturation | None = None
    hysteresis: Hysteresis | None = None
    sensor_dynamics: SensorDynamics | None = None
    amplitude_damping: AmplitudeDamping | None = Field(
        None, description="needs sensor_dynamics (its natural frequency and reference damping)")
    time_delay: TimeDelay | None = None
    jerk_sensitivity: JerkSensitivity | None = None
    g_sensitivity: GSensitivity | None = None
    cross_axis: CrossAxis | None = None
    misalignment: Misalignment | None = None
    excess_noise: ExcessNoise | None = None
    plugin_effects: list[PluginEffect] | None = Field(
        None, description="effects from installed plugins (aatest.effects), applied after the "
        "built-in chain: in °/s² before the scale factor or in volts, as each plugin declares")
    bias_drift: BiasDrift | None = None
    rotor_stiction: RotorStiction | None = None
    jerk_distortion: JerkDistortion | None = None

    @model_validator(mode="after")
    def _damping_has_dynamics(self) -> SensorModel:
        if self.amplitude_damping is not None and self.sensor_dynamics is None:
            raise ValueError("amplitude_damping needs sensor_dynamics (the natural frequency "
                             "and the damping at reference_dps2)")
        return self


class AxisModel(_Model):
    """One table axis: limits, servo and the table-side effects seen by log and sensor alike."""

    rate_limit_dps: float = INNER_RATE_DPS
    accel_limit_dps2: float = INNER_ACCEL_DPS2
    servo_bandwidth_hz: float = 40.0
    encoder_resolution_deg: float = 0.01 / 3600.0
    encoder_noise_deg: float = 0.2 / 3600.0
    estimate_noise_deg: float = Field(
        0.0, ge=0, description="white noise of the controller's position estimate (the rate and "
        "acceleration estimates are its differences); ≈0.01″ reproduces the measured ≈30 °/s² "
        "acceleration-estimate noise at 2 kHz")
    rate_ripple: list[RateRipple] = Field(default_factory=list)
    motor_vibration: MotorVibration | None = None
    encoder_error: EncoderError | None = None
    motor_off_drift_dps: float = Field(0.002, description="slow drift while the motor is off")


class TableModel(_Model):
    """The two-axis table and its controller/estimator."""

    inner: AxisModel = AxisModel()
    outer: AxisModel = AxisModel(rate_limit_dps=OUTER_RATE_DPS, accel_limit_dps2=OUTER_ACCEL_DPS2)
    controller_rate_hz: float = 5000.0
    log_rate_hz: float = LOG_RATE_HZ
    log_capacity_samples: int = LOG_CAPACITY_SAMPLES
    estimator: Literal["central", "five_point"] = "central"
    wobble_arcsec: float = 2.0
    orthogonality_arcsec: float = 3.0
    #: payload imbalance: outer-axis excitation leaks into parasitic motion up to ≈35 Hz
    unbalance_parasitic_dps2_per_dps2: float = 0.0
    unbalance_resonance_hz: float = Field(
        35.0, gt=0, description="the controller's correction of the unbalance torque rings at "
        "this frequency: the leak is k·α_o through a 2nd-order resonance")
    unbalance_damping: float = Field(0.1, gt=0)
    floor_vibration_rms_dps2: float = Field(
        0.0, ge=0, description="building vibration: band-limited rocking of the whole table "
        "about the two horizontal lab axes (RMS per axis); sensors with a horizontal input "
        "axis pick it up, a vertical one does not (docs/method.md §1.3)")
    floor_vibration_band_hz: tuple[float, float] = (5.0, 30.0)


def _stated_logger() -> LoggerSpec:
    """The documented rig's logger as its rig description states it (the one source)."""
    from aatest.engine.rig_description import LoggerSpec

    return LoggerSpec()


class DaqModel(_Model):
    """The on-table sensor logger with its own crystal clock."""

    sample_rate_hz: float = LOG_RATE_HZ
    clock_drift: ClockDrift | None = None
    start_lead_s: float = Field(0.35, ge=0, description="DAQ starts logging this much earlier")
    stop_lag_s: float = Field(0.4, ge=0, description="and stops this much later (by hand)")
    timestamp_jitter_s: float = Field(6e-6, ge=0)
    antialias_hz: float | None = Field(100.0, description="pre-sample filter corner; None = off")
    adc_bits: int = Field(default_factory=lambda: _stated_logger().bits, ge=8, le=32,
                          description="converter resolution (default: the rig description's "
                          "stated logger, 16 bit)")
    adc_range_v: tuple[float, float] = Field(
        default_factory=lambda: _stated_logger().range_v,
        description="converter input range, V (default: the stated logger's, ±10 V)")
    sync_pulse_hz: float = 100.0
    sync_edge_jitter_s: float = Field(
        0.0, ge=0, description="RMS timing jitter of the generated pulse edges (what the "
        "table latches) against the DAQ's sample clock; ≈3 µs reproduces the measured "
        "2.4–3.5 µs clock-relation residual (docs/method.md §2)")
    slip_ring: ExcessNoise | None = None
    logger_error: LoggerError | None = None

    def with_logger(self, stated: LoggerSpec) -> DaqModel:
        """This logger with the converter the rig description states (bits and range)."""
        return self.model_copy(update={"adc_bits": stated.bits,
                                       "adc_range_v": tuple(stated.range_v)})


class ChamberModel(_Model):
    """Temperature chamber and the sensor's first-order thermal lag."""

    ambient_c: float = 22.0
    sensor_time_constant_s: float = Field(300.0, gt=0)
    stable_band_c: float = Field(0.2, gt=0)


class UnitModel(_Model):
    """Three-sensor mounting block: random re-mount perturbations (1σ, degrees)."""

    sensor_remount_sigma_deg: float = 0.05
    block_remount_sigma_deg: float = 0.15
    initial_mount_errors: bool = Field(
        False, description="draw the first mounting from the same spreads (realistic rig); "
        "False: the unit starts perfectly mounted and only re-mounts perturb it")


class RigModel(_Model):
    """The whole simulated rig; the YAML the twin loads and diagnose writes."""

    t_ref_c: float = 25.0
    sensors: list[SensorModel] = Field(default_factory=lambda: [SensorModel()])
    table: TableModel = TableModel()
    daq: DaqModel = DaqModel()
    chamber: ChamberModel = ChamberModel()
    unit: UnitModel = UnitModel()

    def draw_imperfections(self, seed: int, instruments: Instruments | None = None) -> RigModel:
        """This rig with the instrument errors a calibration budget must cover, drawn (seeded)
        uniformly within the rig description's stated specifications.

        Logger gain and offset error within its gain and offset accuracy; an encoder error at
        the encoder's stated error period whose peak stays within its accuracy;
        the lab temperature within the stated tolerance about the reference temperature; the
        first mounting drawn with a spread that keeps the mounting misalignment within the
        stated mounting accuracy (3σ per angle). The model itself is unchanged (defaults stay
        deterministic); the returned copy is what a World is built from.

        Parameters
        ----------
        seed
            Seed of the draws (independent of the World's noise seed).
        instruments
            The stated specifications (default: the documented rig's).
        """
        from aatest.engine.rig_description import Instruments

        spec = instruments if instruments is not None else Instruments()
        rng = np.random.default_rng([int(seed), 0x1A7E])
        logger = LoggerError(
            gain_error=float(rng.uniform(-1, 1)) * spec.logger.gain_accuracy_pct / 100.0,
            offset_v=float(rng.uniform(-1, 1)) * spec.logger.offset_accuracy_v,
            timing_offset_s=float(rng.uniform(-1, 1)) * spec.logger.timing_accuracy_us * 1e-6)
        encoder = EncoderError(
            harmonic_deg=spec.encoder.accuracy_arcsec / 3600.0 * float(rng.uniform(0.0, 1.0)),
            harmonic_cycles_per_rev=spec.encoder.error_cycles_per_rev,
            harmonic_phase_rad=float(rng.uniform(0, 2 * np.pi)))
        lab = spec.lab
        ambient_c = lab.reference_temperature_c + float(rng.uniform(-1, 1)) * \
            lab.temperature_tolerance_c
        sigma_deg = spec.mounting_accuracy_deg / 3.0 / float(np.sqrt(2.0))  # block and seat
        table = self.table.model_copy(update={
            "inner": self.table.inner.model_copy(update={"encoder_error": encoder}),
            "outer": self.table.outer.model_copy(update={"encoder_error": encoder})})
        return self.model_copy(update={
            "daq": self.daq.with_logger(spec.logger).model_copy(
                update={"logger_error": logger}),
            "table": table,
            "chamber": self.chamber.model_copy(update={"ambient_c": ambient_c}),
            "unit": self.unit.model_copy(update={
                "initial_mount_errors": True, "sensor_remount_sigma_deg": sigma_deg,
                "block_remount_sigma_deg": sigma_deg}),
        })

    def sensor(self, channel: str) -> SensorModel:
        for s in self.sensors:
            if s.channel == channel:
                return s
        raise KeyError(channel)


def load_rig_model(path: str | Path) -> RigModel:
    """Load a model YAML safely; errors carry file:line:column (via the engine loader)."""
    from aatest.positioned_yaml import load_model_file

    return load_model_file(Path(path), RigModel)


def dump_rig_model(model: RigModel, path: str | Path) -> None:
    """Write a model YAML that :func:`load_rig_model` reads back unchanged."""
    from ruamel.yaml import YAML

    yaml = YAML(typ="safe", pure=True)
    yaml.default_flow_style = False
    # an object shared by two places (the same effect on both axes) is written out twice, not
    # as an anchor and alias: every YAML aatest reads refuses aliases (unbounded expansion)
    yaml.representer.ignore_aliases = lambda *_args: True
    with Path(path).open("w", encoding="utf-8") as fh:
        yaml.dump(model_document(model), fh)


def model_document(model: BaseModel) -> dict:
    """JSON-able dict of a model that omits switched-off effects (None where the default is
    None) but keeps an explicit ``null`` where None overrides a non-None default (e.g.
    ``antialias_hz: null``), so the YAML round trip is exact."""
    doc: dict = {}
    for name, field in type(model).model_fields.items():
        value = getattr(model, name)
        if value is None:
            if field.default is not None:
                doc[name] = None
        elif isinstance(value, BaseModel):
            doc[name] = model_document(value)
        elif isinstance(value, list):
            doc[name] = [model_document(v) if isinstance(v, BaseModel) else v for v in value]
        else:
            doc[name] = model.model_dump(mode="json", include={name})[name]
    return doc
