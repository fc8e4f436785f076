"""Replay: the commanded motion of every step, on the table's time grid, next to the sensor.

Diagnose compares each sensor channel with what the *nominal* twin predicts from the
*commanded* motion (docs/interfaces.md §4 step 1). The commanded motion is known in form from the
step (a hold, a constant rate, a sine at the commanded frequency) and is aligned on the table
log by least squares — offset, rate and the sine's amplitude and phase — so the servo's
steady-state lag is not mistaken for a sensor effect, while everything the table adds on top of
the command (ripple, vibration) stays in the residual and is visible in the table log itself.

Units: degrees, seconds, °/s, °/s², volts, °C.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from aatest.clocksync.edges import joint_slope_range
from aatest.clocksync.freeze_pulse import ClockRelation, SyncedStep, clock_relation, synchronise
from aatest.engine.errors import AnalysisError
from aatest.engine.steps import PlannedStep
from aatest.metrology.logger_rails import converter_of, noted_at_rails
from aatest.recording.dataset import Dataset, StepData
from aatest.twin import kinematics as kin

#: samples of analytic motion computed beyond each end of a record, so that delays and
#: filters applied to the prediction start in steady state (0.5 s at 2 kHz)
PAD_SAMPLES = 1024
#: commanded-acceleration evaluations kept per step (3 × padded samples each; a 2^17-sample
#: step holds 3.2 MB per entry, so the memo is kept short)
ALPHA_MEMO = 4


@dataclass(frozen=True)
class AxisMotion:
    """θ(t) = offset + rate·t + s·sin(ωt) + c·cos(ωt) of one axis (t from record start).

    The commanded form of the step, with coefficients fitted on the table's position log.
    """

    offset_deg: float = 0.0
    rate_dps: float = 0.0
    sin_deg: float = 0.0
    cos_deg: float = 0.0
    frequency_hz: float = 0.0
    #: whether the rate was a fitted term (a ramp) rather than fixed at zero
    fitted_rate: bool = False

    def basis(self, time_s: np.ndarray) -> np.ndarray:
        """The columns this form was fitted with, at ``time_s``: 1, [t], [sin ωt, cos ωt]."""
        t = np.asarray(time_s, dtype=float)
        cols = [np.ones_like(t)]
        if self.fitted_rate:
            cols.append(t)
        if self.frequency_hz > 0.0:
            w = 2 * np.pi * self.frequency_hz
            cols += [np.sin(w * t), np.cos(w * t)]
        return np.column_stack(cols)

    @property
    def moving(self) -> bool:
        return self.rate_dps != 0.0 or (self.frequency_hz > 0.0 and self.amplitude_deg > 0.0)

    @property
    def amplitude_deg(self) -> float:
        return float(np.hypot(self.sin_deg, self.cos_deg))

    def acceleration(self, time_s: np.ndarray) -> np.ndarray:
        """The accel_dps2 of :meth:`evaluate` alone (the same arithmetic, a third of it)."""
        t = np.asarray(time_s, dtype=float)
        accel = np.zeros_like(t)
        if self.frequency_hz > 0.0:
            w = 2 * np.pi * self.frequency_hz
            accel = accel - w * w * (self.sin_deg * np.sin(w * t) + self.cos_deg * np.cos(w * t))
        return accel

    def evaluate(self, time_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(angle_deg, rate_dps, accel_dps2) at times ``time_s`` (s from record start)."""
        t = np.asarray(time_s, dtype=float)
        angle = self.offset_deg + self.rate_dps * t
        rate = np.full_like(t, self.rate_dps)
        accel = np.zeros_like(t)
        if self.frequency_hz > 0.0:
            w = 2 * np.pi * self.frequency_hz
            s, c = np.sin(w * t), np.cos(w * t)
            angle = angle + self.sin_deg * s + self.cos_deg * c
            rate = rate + w * (self.sin_deg * c - self.cos_deg * s)
            accel = accel - w * w * (self.sin_deg * s + self.cos_deg * c)
        return angle, rate, accel


def fit_axis_motion(time_s: np.ndarray, position_deg: np.ndarray, moving: bool,
                    frequency_hz: float | None, constant_rate: bool) -> AxisMotion:
    """Align the commanded form on the logged position by linear least squares.

    A sine keeps only its fundamental (the commanded component), a ramp its straight line;
    anything else the table did stays in the log's residual.
    """
    t = np.asarray(time_s, dtype=float)
    pos = np.asarray(position_deg, dtype=float)
    columns = [np.ones_like(t)]
    if moving and constant_rate:
        columns.append(t)
    f_hz = float(frequency_hz) if moving and frequency_hz is not None else 0.0
    use_sine = f_hz > 0.0
    if use_sine:
        w = 2 * np.pi * f_hz
        columns += [np.sin(w * t), np.cos(w * t)]
    coef, *_ = np.linalg.lstsq(np.column_stack(columns), pos, rcond=None)
    coef = list(coef)
    offset = coef.pop(0)
    rate = coef.pop(0) if moving and constant_rate else 0.0
    ramp = moving and constant_rate
    if use_sine:
        return AxisMotion(offset, rate, coef[0], coef[1], f_hz, ramp)
    return AxisMotion(offset, rate, fitted_rate=ramp)


@dataclass(frozen=True)
class StepReplay:
    """One synchronised step: the measured channels and the commanded motion behind them."""

    index: int
    step: PlannedStep
    time_s: np.ndarray
    dt_s: float
    volts: dict[str, np.ndarray]
    temperature_c: np.ndarray | None
    inner: AxisMotion
    outer: AxisMotion
    #: logged position minus the commanded motion, per axis (what the table added), degrees
    table_deviation_deg: dict[str, np.ndarray]
    relation: ClockRelation | None
    pivoted: bool = False
    motor_on: bool = True
    #: memo of motion evaluations (delay/warp searches re-use them), not part of the value
    memo: dict = field(default_factory=dict, compare=False, repr=False)

    @property
    def n(self) -> int:
        return int(self.time_s.size)

    @property
    def padded_time_s(self) -> np.ndarray:
        """Record times extended by :data:`PAD_SAMPLES` on each side (read-only, memoised:
        every column build evaluates the motion on it)."""
        value = self.memo.get(("padded_time_s",))
        if value is None:
            value = self.dt_s * np.arange(-PAD_SAMPLES, self.n + PAD_SAMPLES)
            value.flags.writeable = False
            self.memo[("padded_time_s",)] = value
        return value

    @property
    def dynamic(self) -> bool:
        return self.inner.frequency_hz > 0.0 or self.outer.frequency_hz > 0.0

    def motion(self, time_s: np.ndarray) -> dict[str, np.ndarray]:
        """Both axes' (angle, rate, accel) at ``time_s``, keyed ``inner_angle`` …"""
        out: dict[str, np.ndarray] = {}
        for name, axis in (("inner", self.inner), ("outer", self.outer)):
            out[f"{name}_angle"], out[f"{name}_rate"], out[f"{name}_accel"] = axis.evaluate(time_s)
        return out


def sensor_axes(axis: str, pivoted: bool) -> np.ndarray:
    """Sensor (x, y, z) as columns in table-top coordinates for a seat on ``axis``.

    The pivoted mounting turns the sensor 180° about its sensitive axis (x, y flip).
    """
    frame = kin.SEAT_FRAMES[axis]
    return frame @ np.diag([-1.0, -1.0, 1.0]) if pivoted else frame


def ripple_regressors(replay: StepReplay, time_s: np.ndarray, n_cpd: float
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Unit inner-axis ripple sin/cos(2π·n·θ) as (position s, c, acceleration s, c) at ``time_s``.

    The part of the ripple the commanded form can absorb (its projection on the form's
    columns over the record) is removed, because the replay's reference was fitted on a
    table log that contains the ripple: what remains is what the reference cannot explain.
    """
    axis = replay.inner
    k = 2 * np.pi * n_cpd
    angle, rate, accel = axis.evaluate(time_s)
    s, c = np.sin(k * angle), np.cos(k * angle)
    acc_s, acc_c = c * k * accel - s * (k * rate) ** 2, -s * k * accel - c * (k * rate) ** 2
    key = ("ripple_projection", n_cpd)
    if key not in replay.memo:
        rec_angle = axis.evaluate(replay.time_s)[0]
        replay.memo[key] = np.linalg.lstsq(
            axis.basis(replay.time_s),
            np.column_stack([np.sin(k * rec_angle), np.cos(k * rec_angle)]), rcond=None)[0]
    coef = replay.memo[key]
    full = axis.basis(time_s)
    pos_s, pos_c = s - full @ coef[:, 0], c - full @ coef[:, 1]
    if axis.frequency_hz > 0.0:
        w2 = (2 * np.pi * axis.frequency_hz) ** 2
        sin_cos = full[:, -2:]
        acc_s = acc_s + w2 * (sin_cos @ coef[-2:, 0])
        acc_c = acc_c + w2 * (sin_cos @ coef[-2:, 1])
    return pos_s, pos_c, acc_s, acc_c


def _sincos(angle_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(sin, cos) of an angle array; a constant angle is evaluated once."""
    a = np.asarray(angle_deg, dtype=float)
    if a.size and a[0] == a[-1] and np.all(a == a[0]):
        rad = np.radians(a[0])
        return np.full_like(a, np.sin(rad)), np.full_like(a, np.cos(rad))
    rad = np.radians(a)
    return np.sin(rad), np.cos(rad)


def sensor_acceleration(replay: StepReplay, axis: str, time_s: np.ndarray,
                        memo_key: tuple | None = None) -> np.ndarray:
    """Commanded angular acceleration in the sensor frame, (3, n) rows x, y, z (°/s²).

    With ``memo_key`` the result is kept on the step (the :data:`ALPHA_MEMO` most recently
    used), for repeated evaluations on the same time grid during a parameter search (the
    dynamics, hysteresis and saturation searches re-use one grid; a delay search moves it).
    """
    if memo_key is not None:
        key = ("alpha", axis, memo_key)
        value = replay.memo.pop(key, None)
        if value is None:
            value = sensor_acceleration(replay, axis, time_s)
            alphas = [k for k in replay.memo if k[0] == "alpha"]
            for old in alphas[: max(len(alphas) - ALPHA_MEMO + 1, 0)]:
                del replay.memo[old]
        replay.memo[key] = value  # most recently used last
        return value
    if not replay.outer.moving:
        # the outer axis still: its rate and acceleration are zero, every term of the top's
        # acceleration but the inner axis's own is zero and the inner angle's sine and cosine
        # (half of the evaluation) are not needed (kinematics.angular_acceleration_top)
        top = np.zeros((3, np.size(time_s)))
        top[2] = replay.inner.acceleration(time_s)
        return sensor_axes(axis, replay.pivoted).T @ top
    m = replay.motion(time_s)
    top = kin.angular_acceleration_top(_sincos(m["inner_angle"]), m["inner_rate"],
                                       m["inner_accel"], m["outer_rate"], m["outer_accel"])
    return sensor_axes(axis, replay.pivoted).T @ top


def sensor_rate(replay: StepReplay, axis: str, time_s: np.ndarray) -> np.ndarray:
    """Commanded angular rate about the sensor's sensitive axis, (n,) °/s."""
    m = replay.motion(time_s)
    top = kin.angular_rate_top(_sincos(m["inner_angle"]), m["inner_rate"], m["outer_rate"])
    return np.asarray(sensor_axes(axis, replay.pivoted)[:, 2] @ top)


def gravity_along(replay: StepReplay, axis: str) -> np.ndarray:
    """Specific force along the sensor's sensitive axis (g), on the record grid."""
    m = replay.motion(replay.time_s)
    up = kin.gravity_top(_sincos(m["inner_angle"]), _sincos(m["outer_angle"]))
    return sensor_axes(axis, replay.pivoted)[:, 2] @ up


def _position(table: dict[str, np.ndarray], axis: str, step: PlannedStep) -> np.ndarray:
    """Logged position of ``axis``; import data name the moving axis ``position_deg``."""
    for key in (f"{axis}_position_deg", "position_deg"):
        if key in table:
            return np.asarray(table[key], dtype=float)
    fallback = step.inner_deg if axis == "inner" else step.outer_deg
    return np.full(len(next(iter(table.values()))), fallback)


def replay_step(index: int, synced: SyncedStep, channels: list[str]) -> StepReplay:
    """Fit the commanded motion of one synchronised step on its table log."""
    step = synced.step
    t = np.asarray(synced.time_s, dtype=float) - float(synced.time_s[0])
    axes: dict[str, AxisMotion] = {}
    deviation: dict[str, np.ndarray] = {}
    for name in ("inner", "outer"):
        moves = _axis_moves(step, name)
        pos = _position(dict(synced.table), name, step)
        axes[name] = fit_axis_motion(t, pos, moves, step.frequency_hz if step.kind == "sine"
                                     else None, step.kind == "constant_rate")
        deviation[name] = pos - axes[name].evaluate(t)[0]
    temp = synced.daq.get("temperature_c")
    return StepReplay(
        index=index, step=step, time_s=t, dt_s=1.0 / synced.sample_rate_hz,
        volts={ch: np.asarray(synced.daq[ch], dtype=float) for ch in channels},
        temperature_c=None if temp is None else np.asarray(temp, dtype=float),
        inner=axes["inner"], outer=axes["outer"], table_deviation_deg=deviation,
        relation=synced.relation if synced.relation.edges_used > 0 else None,
        pivoted=step.mounting.pivoted, motor_on=step.motor_on,
    )


def _axis_moves(step: PlannedStep, axis: str) -> bool:
    if step.kind == "sine":
        return (step.axis == "outer") == (axis == "outer") or step.axis == "both"
    if step.kind == "constant_rate":
        if axis == "outer":
            return step.axis == "outer" or bool(step.outer_rate_dps)
        return not (step.axis == "outer" and step.outer_rate_dps is None)
    return False


@dataclass(frozen=True)
class Replay:
    """All recorded steps of a dataset, synchronised and aligned on their commands."""

    dataset: Dataset
    steps: tuple[StepReplay, ...]
    channels: tuple[str, ...]
    fp_latch: bool
    t_ref_c: float
    skipped: tuple[str, ...] = field(default=())
    #: steps left out because the logger clipped them: step id → {channel: samples at a rail}
    clipped: dict[str, dict[str, int]] = field(default_factory=dict)

    @property
    def dt_s(self) -> float:
        return self.steps[0].dt_s


def replay_dataset(dataset: Dataset) -> Replay:
    """Synchronise every recorded step and fit its commanded motion.

    Raises
    ------
    AnalysisError
        When no step can be synchronised.
    """
    channels = [s.channel for s in dataset.sensors]
    steps: list[StepReplay] = []
    skipped: list[str] = []
    clipped = clipped_steps(dataset)
    for data, relation in _relations(dataset, set(clipped)):
        synced = _synchronised(data, relation)
        if synced is None:
            skipped.append(data.step.id)
            continue
        steps.append(replay_step(len(steps), synced, channels))
    if not steps:
        raise AnalysisError(f"{dataset.source}: no step could be synchronised" + (
            f" ({len(clipped)} left out: the logger clipped them)" if clipped else ""))
    fp = all("fp_latch_s" in s.table.channels for s in dataset.steps)
    present = dataset.metadata.get("fp_latch_s_present")
    if present is not None:
        fp = bool(present)
    t_ref = dataset.metadata.get("t_ref_c")
    model = dataset.metadata.get("model")
    if not isinstance(t_ref, (int, float)) and isinstance(model, dict):
        t_ref = model.get("t_ref_c")
    return Replay(dataset, tuple(steps), tuple(channels), fp,
                  float(t_ref) if isinstance(t_ref, (int, float)) else 25.0, tuple(skipped),
                  clipped)


def clipped_steps(dataset: Dataset) -> dict[str, dict[str, int]]:
    """Recorded steps whose sensor channels hold samples at the rails of the data's stated
    logger (:mod:`aatest.metrology.logger_rails`): step id → {channel: samples}.

    Why they are left out: a clipped record's flat tops are the logger's, and a sensor model
    fitted to them names effects the sensor does not have (a 0…3.6 V logger under 2.5 ± 1.6 V
    sines made a clean twin's diagnosis name a cubic non-linearity c3 = −0.44).
    """
    logger = converter_of(dataset.metadata)[0]
    found = {}
    for data in dataset.steps:
        if not data.step.recorded:
            continue
        counts = {ch: noted_at_rails(noted, logger)
                  for ch, noted in data.daq_extremes().items()}
        if any(counts.values()):
            found[data.step.id] = {ch: n for ch, n in counts.items() if n}
    return found


def _relation_or_none(data: StepData, slope_range: tuple[float, float] | None = None
                      ) -> ClockRelation | None:
    """The step's clock relation from its sync edges, None when they cannot give one."""
    try:
        return clock_relation(data, slope_range)
    except AnalysisError:
        return None


def _relations(dataset: Dataset, left_out: set[str]
               ) -> list[tuple[StepData, ClockRelation | None]]:
    """Every recorded step (but those ``left_out``) with its clock relation, one DAQ crystal
    across the steps.

    Without latch times a step's edges bound the drift only to about one sample over its record
    (≈ 120 ppm on a 4 s record at 2 kHz); the centre of that range can sit tens of ppm off, and
    on a fast sine the phase then slides by a visible fraction of a sample through the record —
    structure no sensor has. One crystal drives the DAQ through every step, so each step's
    relation is refitted inside the rates all steps allow together
    (:func:`~aatest.clocksync.edges.joint_slope_range`); the offsets left open stay a nuisance of
    the nominal fit (:mod:`aatest.diagnose.alignment`).
    """
    recorded = [d for d in dataset.steps if d.step.recorded and d.step.id not in left_out]
    first = [_relation_or_none(d) for d in recorded]
    found = [r for r in first if r is not None]
    joint = None if any(r.latched for r in found) else joint_slope_range(found)
    if joint is None:
        return list(zip(recorded, first, strict=True))
    return [(d, r if r is None else _relation_or_none(d, joint) or r)
            for d, r in zip(recorded, first, strict=True)]


def _synchronised(data: StepData, relation: ClockRelation | None) -> SyncedStep | None:
    """Freeze-pulse sync, else trigger alignment (one clock; drift then from the phase trend)."""
    if relation is not None:
        try:
            return synchronise(data, relation)
        except AnalysisError:
            pass
    from aatest.diagnose.trigger_alignment import trigger_aligned

    return trigger_aligned(data)
