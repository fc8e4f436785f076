"""Temperature test: bias and scale factor against sensor temperature (docs/method.md §4.2).

The sensor temperature of a step is the mean of the DAQ's ``temperature_c`` channel (else the
chamber set-point). Static steps give the bias line V = b0 + c·(T − 25 °C) (+ a gravity term
when orientations differ), its slope with 95 % bounds against the ±0.4 mV/°C datasheet limit,
the hysteresis between the cooling and the heating branch (largest difference of the two
branches interpolated on their common temperatures) and the noise at every step. Sine steps
(the dynamic variant) give the FRF gain per temperature and so the scale-factor coefficient
K(T) = K₀(1 + c·(T − 25 °C)) against 0.05 %/°C.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any, ClassVar

import numpy as np

from aatest.clocksync.freeze_pulse import SyncedStep
from aatest.engine.interfaces import AnalysisContext, AnalysisOutput, NoOptions
from aatest.engine.requirements import Requirement
from aatest.engine.steps import PlannedStep
from aatest.plugins.analysis import needs
from aatest.plugins.analysis._common import (
    fundamental,
    input_accel_dps2,
    is_excited,
    select,
    steps_of,
    t95,
)
from aatest.plugins.analysis.bias import gravity_along_g
from aatest.plugins.analysis.polyfit import fit_polynomial
from aatest.plugins.analysis.streaming import Moments, reduce_static
from aatest.plugins.analysis.sync import SyncedSteps
from aatest.presentation.figures import new_figure, tight_layout, to_svg
from aatest.recording.dataset import Dataset, LazySteps, SensorInfo
from aatest.results.temperature import TemperatureResult

T_REF_C = 25.0
_TEMPERATURE = "temperature_c"
_MIN_SPAN_C = 5.0
#: temperatures a coefficient needs (a slope and a check of it)
_MIN_SETPOINTS = 3
#: points each branch (cooling, heating) needs for a hysteresis
_MIN_BRANCH_POINTS = 2
#: spread of the gravity component (g) above which it joins the bias fit
_MIN_G_SPREAD = 0.5


def step_temperature_c(step: SyncedStep) -> float | None:
    """Mean sensor temperature of a step, °C (None when neither log nor plan has one), read
    block by block."""
    found = reduce_static(step.daq_blocks([_TEMPERATURE]), [_TEMPERATURE],
                          step.sample_rate_hz, len(step))
    mean = found[_TEMPERATURE].moments.mean if _TEMPERATURE in found else None
    if mean is not None and np.isfinite(mean):
        return float(mean)
    return step.step.temperature_c


def _static_row(step: SyncedStep, sensor: SensorInfo) -> tuple[float | None, float, float]:
    """(mean temperature °C, mean V, standard deviation V) of a static record, one pass."""
    found = reduce_static(step.daq_blocks([_TEMPERATURE, sensor.channel]),
                          [_TEMPERATURE, sensor.channel], step.sample_rate_hz, len(step))
    volts = found[sensor.channel].moments
    temp = found[_TEMPERATURE].moments.mean if _TEMPERATURE in found else None
    temp_c = float(temp) if temp is not None and np.isfinite(temp) else step.step.temperature_c
    return temp_c, volts.mean, volts.std


def _slope(x: np.ndarray, y: np.ndarray, extra: np.ndarray | None = None
           ) -> tuple[float, float, float, float]:
    """Intercept, slope, slope std uncertainty and 95 % half-width of y = a + b·x (+ c·extra)."""
    spread = extra is not None and np.ptp(extra) > _MIN_G_SPREAD
    cols = [np.ones_like(x), x] + ([extra] if extra is not None and spread else [])
    design = np.column_stack(cols)
    coef, *_ = np.linalg.lstsq(design, y, rcond=None)
    resid = y - design @ coef
    dof = max(y.size - design.shape[1], 1)
    cov = np.linalg.pinv(design.T @ design) * float(resid @ resid) / dof
    u = float(np.sqrt(cov[1, 1]))
    return float(coef[0]), float(coef[1]), u, t95(dof) * u


def branches(temps: np.ndarray) -> np.ndarray:
    """+1 for steps on a heating branch, −1 on a cooling branch (by the step sequence)."""
    diff = np.diff(temps, prepend=temps[0])
    sign = np.sign(diff)
    for i in range(sign.size):  # a step that does not move keeps its predecessor's branch
        if sign[i] == 0:
            sign[i] = sign[i - 1] if i else -1
    return sign


def hysteresis_v(temps: np.ndarray, values: np.ndarray) -> float | None:
    """Largest |heating − cooling| difference on the branches' common temperature range."""
    side = branches(temps)
    cool, heat = side < 0, side > 0
    if cool.sum() < _MIN_BRANCH_POINTS or heat.sum() < _MIN_BRANCH_POINTS:
        return None
    lo = max(temps[cool].min(), temps[heat].min())
    hi = min(temps[cool].max(), temps[heat].max())
    if hi <= lo:
        return None
    grid = np.linspace(lo, hi, 50)
    oc, oh = np.argsort(temps[cool]), np.argsort(temps[heat])
    v_cool = np.interp(grid, temps[cool][oc], values[cool][oc])
    v_heat = np.interp(grid, temps[heat][oh], values[heat][oh])
    return float(np.max(np.abs(v_heat - v_cool)))


def bias_vs_temperature(steps: Sequence[SyncedStep], sensor: SensorInfo) -> dict[str, Any]:
    """Bias slope, hysteresis and noise of one sensor over the static steps."""
    rows = [(*_static_row(s, sensor),
             gravity_along_g(sensor.axis, s.step.inner_deg, s.step.outer_deg))
            for s in steps]  # one pass: each step is read (synchronised) once
    temps = np.array([r[0] for r in rows], dtype=float)
    volts = np.array([r[1] for r in rows])
    noise = np.array([r[2] for r in rows])
    g = np.array([r[3] for r in rows])
    b0, c, u, half = _slope(temps - T_REF_C, volts, g)
    return {
        "bias_coefficient_v_per_c": c, "bias_coefficient_u_v_per_c": u,
        "bias_coefficient_ci95_v_per_c": [c - half, c + half], "bias_at_25c_v": b0,
        "hysteresis_v": hysteresis_v(temps, volts - c * (temps - T_REF_C)),
        "temperatures_c": temps.tolist(), "bias_v": volts.tolist(), "noise_rms_v": noise.tolist(),
        "branch": ["heating" if b > 0 else "cooling" for b in branches(temps)],
    }


def _gain(step: SyncedStep, sensor: SensorInfo) -> complex:
    """Sensor output over table input at the excitation bin, V/(°/s²)."""
    f0, fs = float(step.step.frequency_hz or 1.0), step.sample_rate_hz
    return fundamental(step.daq[sensor.channel], f0, fs) / fundamental(
        input_accel_dps2(step, sensor.axis), f0, fs)


def scale_vs_temperature(steps: Sequence[SyncedStep], sensor: SensorInfo) -> dict[str, Any]:
    """Scale-factor temperature coefficient from the sine steps' fundamental gains."""
    rows = [(step_temperature_c(s), abs(_gain(s, sensor))) for s in steps]  # one read each
    temps = np.array([r[0] for r in rows], dtype=float)
    gains = np.array([r[1] for r in rows])
    fit = fit_polynomial(temps - T_REF_C, gains, 1)
    (k0, b), cov = fit.coefficients, fit.covariance
    c = b / k0
    grad = np.array([-b / k0**2, 1.0 / k0])
    u = float(np.sqrt(grad @ cov @ grad))
    half = t95(fit.dof) * u
    return {
        "scale_coefficient_per_c": float(c), "scale_coefficient_u_per_c": u,
        "scale_coefficient_ci95_per_c": [float(c - half), float(c + half)],
        "scale_at_25c_v_per_dps2": float(k0),
        "scale_temperatures_c": temps.tolist(), "scale_v_per_dps2": gains.tolist(),
        "scale_hysteresis_per_c_ref": hysteresis_v(temps, gains / k0 - c * (temps - T_REF_C)),
    }


def _figure(row: dict[str, Any], channel: str) -> str:
    """Bias (and scale factor) against temperature, cooling and heating branches marked."""
    rows = 2 if "scale_temperatures_c" in row else 1
    fig, ax = new_figure(rows, height_in=2.4)
    temps, bias = np.array(row["temperatures_c"]), np.array(row["bias_v"])
    for name, marker in (("cooling", "v"), ("heating", "^")):
        sel = np.array(row["branch"]) == name
        ax[0, 0].plot(temps[sel], bias[sel] * 1e3, marker, ms=4, label=name)
    ax[0, 0].set(xlabel="sensor temperature / °C", ylabel="bias / mV", title=f"{channel}")
    ax[0, 0].legend(fontsize=6)
    if rows > 1:
        ax[1, 0].plot(row["scale_temperatures_c"], np.array(row["scale_v_per_dps2"]) * 1e3, "o",
                      ms=4)
        ax[1, 0].set(xlabel="sensor temperature / °C", ylabel="scale / (mV/(°/s²))")
    tight_layout(fig)
    return to_svg(fig)


def _point(step: PlannedStep) -> tuple[float, float | None]:
    return round(float(step.frequency_hz or 0), 6), step.accel_dps2


def _same_point(steps: Sequence[SyncedStep], planned: Sequence[PlannedStep]
                ) -> Sequence[SyncedStep]:
    """The sine steps of the (frequency, acceleration) point seen at the most temperatures."""
    if not planned:
        return []
    keys = [_point(p) for p in planned]
    best = max(set(keys), key=keys.count)
    return select(steps, lambda p: _point(p) == best)


def _excited_sine(sensor: SensorInfo) -> Callable[[PlannedStep], bool]:
    """Whether a planned step is a sine step exciting ``sensor``."""
    return lambda p: p.kind == "sine" and is_excited(p, sensor)


def _planned(steps: Sequence[SyncedStep]) -> Sequence[PlannedStep]:
    """The planned steps, without synchronising anything on the lazy view."""
    return steps.planned if isinstance(steps, SyncedSteps) else [s.step for s in steps]


def _spans(steps: Sequence[SyncedStep]) -> bool:
    temps = [t for s in steps if (t := step_temperature_c(s)) is not None]
    return len(temps) >= _MIN_SETPOINTS and (max(temps) - min(temps)) >= _MIN_SPAN_C


def _logged_mean_c(data: Dataset, index: int) -> float | None:
    """Mean logged temperature of recorded step ``index`` (°C), read piece by piece from a
    recording; None when not logged."""
    steps = data.steps
    pieces = (steps.pieces(index, "daq", [_TEMPERATURE]) if isinstance(steps, LazySteps)
              else [steps[index].daq])
    moments = Moments()
    for piece in pieces:
        if _TEMPERATURE not in piece.channels:
            return None
        moments.add(piece[_TEMPERATURE])
    return moments.mean if moments.n else None


class TemperatureAnalysis:
    """Bias, scale factor and noise of every sensor against its temperature."""

    key: ClassVar[str] = "temperature"
    requires: ClassVar[tuple[str, ...]] = ("sync",)
    #: what the plan must hold (checked by ``validate``; aatest.engine.requirements)
    requirements: ClassVar[tuple[Requirement, ...]] = needs.TEMPERATURE
    #: the acceptance quantities it produces (judged when it is listed)
    judges: ClassVar[tuple[str, ...]] = ("bias_temperature_v_per_c", "scale_temperature_per_c")
    #: what the plan must hold for each coefficient (checked when the acceptance asks for it)
    produces: ClassVar[Mapping[str, Requirement]] = needs.TEMPERATURE_PRODUCES
    Options: ClassVar[type[NoOptions]] = NoOptions
    Result: ClassVar[type[TemperatureResult]] = TemperatureResult

    def applies_to(self, data: Dataset) -> bool:
        """At least three set-points, or logged sensor temperatures spanning ≥ 5 °C."""
        temps = {s.step.temperature_c for s in data.steps if s.step.temperature_c is not None}
        if len(temps) >= _MIN_SETPOINTS:
            return True
        logged = [t for i, p in enumerate(data.planned) if p.recorded
                  and (t := _logged_mean_c(data, i)) is not None]
        return len(logged) >= _MIN_SETPOINTS and max(logged) - min(logged) >= _MIN_SPAN_C

    def run(self, data: Dataset, context: AnalysisContext) -> AnalysisOutput[TemperatureResult]:
        steps = steps_of(context)
        values: dict[str, Any] = {}
        figures: dict[str, str] = {}
        for sensor in data.sensors:
            static = select(steps, lambda p: p.kind == "static")
            excited = select(steps, _excited_sine(sensor))
            sine = _same_point(excited, _planned(excited))
            row: dict[str, Any] = {"bias_coefficient_v_per_c": None,
                                   "scale_coefficient_per_c": None, "hysteresis_v": None}
            if _spans(static):
                row |= bias_vs_temperature(static, sensor)
            if _spans(sine):
                row |= scale_vs_temperature(sine, sensor)
            values[sensor.channel] = row
            if "temperatures_c" in row:
                figures[f"temperature_{sensor.channel}"] = _figure(row, sensor.channel)
        return AnalysisOutput(TemperatureResult.model_validate(values), figures)
