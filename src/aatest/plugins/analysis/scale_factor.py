"""Scale-factor calibration from a single-frequency sine (docs/method.md §4.3).

Per sensor: the sine steps along its axis at ≤ 2 Hz at the frequency nearest 1 Hz are grouped
by acceleration level and chamber set-point, and each group is calibrated
(:mod:`.scale_levels`: the headline is the largest level at the set-point nearest 25 °C, the
1 Hz, 70 %-of-range test, and it names that level; the levels give the linearity). Per group,
the records are synchronised; the sensor volts pass a zero-phase low-pass, the reference
is the chosen method's output as that method makes it (default ``smoothed``: the position
estimate's second difference through a zero-phase low-pass at its own 25 Hz corner;
``table_estimate`` is the controller's raw estimate, so
its noise shows in the RMSE as in the study, docs/method.md §4.3), the reference is delayed by
the sensor's phase delay at the fundamental (so the fit sees no phase loop), and polynomials of
order 0–15 are cross-validated. The chosen forward model (°/s² from volts) is reported with its
statistics; the contract's ``scale_v_per_dps2``/``offset_v`` come from the best straight line
(the lab's scale factor); the study's (non)linearity L of Eq. 3.36 — the chosen model's RMS
deviation over the record from the ideal line, the straight line against the table's own
acceleration estimate (g = 250.02·u − 0.319 in the study) — is ``linearity_l_dps2``; an inverse form
(volts from °/s²) is given too. Noise in the reference does not bias the forward fit (it is the
dependent variable), which is why the scale factor is 1/slope of that fit.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from aatest.clocksync.freeze_pulse import SyncedStep
from aatest.engine.errors import AnalysisError
from aatest.engine.interfaces import AnalysisContext, AnalysisOutput
from aatest.engine.requirements import Requirement
from aatest.numerics import Z95
from aatest.plugins.analysis import needs, polyfit
from aatest.plugins.analysis._common import (
    fundamental,
    input_accel_dps2,
    is_excited,
    options_of,
    steps_of,
)
from aatest.plugins.analysis.reference import (
    PUBLIC_METHODS,
    SMOOTHED_CORNER_HZ,
    default_cutoff_hz,
    reference_accel,
    zero_phase_lowpass,
)
from aatest.plugins.analysis.scale_levels import Level, headline_level, level_groups, linearity
from aatest.presentation.figures import new_figure, tight_layout, to_svg
from aatest.recording.dataset import Dataset, SensorInfo
from aatest.results.scale_factor import ReferenceChoice, ReferenceName, ScaleFactorResult

_MAX_CAL_FREQUENCY_HZ = 2.0
#: datasheet threshold/resolution, fraction of the range (0.005 % FR)
RESOLUTION_FR = 0.00005
_MAX_ORDER = 20
#: two planned frequencies closer than this are the same point
_SAME_FREQUENCY_HZ = 1e-9
#: fewer residuals than this have no autocorrelation to speak of
_MIN_RESIDUALS = 3


class ScaleFactorOptions(BaseModel):
    """The reference calibrated against and the order selection (docs/method.md §4.3).

    ``reference``: ``smoothed`` (default; smoothed second difference of the position estimate,
    zero-phase low-pass at its own corner, ``reference.SMOOTHED_CORNER_HZ``),
    ``table_estimate`` (the controller's own estimate), ``central``/``five_point`` (first
    difference of the rate estimate), ``fit`` (Savitzky–Golay local polynomial fit of the
    position) or ``sliding_mode`` (Levant's differentiator of the rate). The old
    implementation names (``smooth``, ``table``, ``savgol``, ``levant``) are accepted.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)
    reference: ReferenceName = "smoothed"
    orders: tuple[int, int] = Field((0, 15), description="lowest and highest order scanned")
    identification_fraction: float = Field(0.25, gt=0, lt=1,
                                           description="share of samples identified on")
    random_splits: int = Field(3, ge=0, description="random splits besides the fixed one")
    seed: int = Field(0, ge=0, description="seed of the random splits")

    @model_validator(mode="after")
    def _orders_ascend(self) -> ScaleFactorOptions:
        low, high = self.orders
        if not 0 <= low <= high <= _MAX_ORDER or high < 1:
            raise ValueError(f"orders must be [low, high] with 0 ≤ low ≤ high ≤ {_MAX_ORDER}, "
                             "high ≥ 1")
        return self


def calibration_candidates(steps: Sequence[SyncedStep], sensor: SensorInfo) -> list[SyncedStep]:
    """The scale-factor candidates of a sensor: sine, along its axis, ≤ 2 Hz, at the frequency
    closest to 1 Hz in octaves, the larger acceleration on a tie (every acceleration level,
    set-point and repetition of it)."""
    cands = [s for s in steps if s.step.kind == "sine" and is_excited(s.step, sensor)
             and (s.step.frequency_hz or 0.0) <= _MAX_CAL_FREQUENCY_HZ]
    if not cands:
        return []
    def departure(s: SyncedStep) -> tuple[float, float]:
        # octaves from 1 Hz (0.5 and 2 Hz are equally far), then the larger acceleration:
        # the 1 Hz, 70 %-of-range test of docs/method.md §4.3 as near as the steps allow
        f = float(s.step.frequency_hz or 0.0)
        return abs(np.log2(f)) if f > 0 else np.inf, -float(s.step.accel_dps2 or 0.0)

    best_f = float(min(cands, key=departure).step.frequency_hz or 0.0)
    return [s for s in cands
            if abs(float(s.step.frequency_hz or 0.0) - best_f) < _SAME_FREQUENCY_HZ]


def fractional_delay(x: np.ndarray, delay_s: float, fs_hz: float) -> np.ndarray:
    """x(t − delay) by an FFT phase ramp (exact for the periodic part of a coherent record).

    Public: the study benches shift references with it as :func:`aligned_pair` does.
    """
    freqs = np.fft.rfftfreq(x.size, 1.0 / fs_hz)
    return np.fft.irfft(np.fft.rfft(x) * np.exp(-2j * np.pi * freqs * delay_s), n=x.size)


def aligned_pair(synced: SyncedStep, sensor: SensorInfo, reference: ReferenceChoice = "smoothed"
                 ) -> tuple[np.ndarray, np.ndarray, float, float]:
    """(volts, reference °/s², delay s, filter corner Hz) of one step, time-aligned.

    The sensor volts pass a zero-phase low-pass (they are the fit's regressor, so their noise
    would bias the slope); the reference is the named method's output as it is (the
    ``smoothed`` one low-passed at its own corner), delayed by the phase delay of the
    sensor at the excitation frequency; filter and shift edges are trimmed.
    """
    fs, f0 = synced.sample_rate_hz, float(synced.step.frequency_hz or 1.0)
    cutoff = default_cutoff_hz(synced)
    method = PUBLIC_METHODS[reference]
    # each reference is used as its method makes it: only ``smoothed`` is low-passed (inside
    # reference_accel); the table estimate, the differences, the local fit and the
    # sliding-mode differentiator keep their own noise, which the fit's RMSE then shows
    ref = input_accel_dps2(synced, sensor.axis, reference_accel(synced, method))
    volts = zero_phase_lowpass(synced.daq[sensor.channel], fs, cutoff)
    ratio = fundamental(volts, f0, fs) / fundamental(ref, f0, fs)
    delay_s = float(-np.angle(ratio * np.sign(ratio.real or 1.0)) / (2 * np.pi * f0))
    ref = fractional_delay(ref, delay_s, fs)
    trim = int(3.0 * fs / cutoff) + int(abs(delay_s) * fs) + 8
    return volts[trim:-trim], ref[trim:-trim], delay_s, cutoff


def _line(volts: np.ndarray, ref_dps2: np.ndarray) -> np.ndarray:
    """Least-squares straight line of the reference on the volts, evaluated (°/s²)."""
    coef = np.polynomial.polynomial.polyfit(volts - volts.mean(), ref_dps2, 1)
    return np.asarray(np.polynomial.polynomial.polyval(volts - volts.mean(), coef))


def correlation_inflation(residual: np.ndarray) -> float:
    """Variance inflation of a mean-like estimate from serially correlated residuals.

    1 + 2·Σ r_k (r_k: the residuals' autocorrelation at lag k) over the lags before the
    autocorrelation first drops to zero (the initial positive sequence): white residuals
    give 1; residuals of a reference whose noise is coloured (ripple, a local fit, a
    differentiator's chatter) give the factor by which the least-squares covariance
    understates the coefficients' variance. Computed by FFT.
    """
    x = np.asarray(residual, dtype=np.float64) - float(np.mean(residual))
    n = x.size
    if n < _MIN_RESIDUALS or not np.any(x):
        return 1.0
    spectrum = np.fft.rfft(x, 2 * n)
    acf = np.fft.irfft(spectrum * np.conj(spectrum), 2 * n)[:n]
    acf = acf / acf[0]
    stop = np.flatnonzero(acf <= 0.0)
    positive = acf[1:int(stop[0])] if stop.size else acf[1:]
    return float(max(1.0, 1.0 + 2.0 * positive.sum()))


def _select_order(u: np.ndarray, ref_dps2: np.ndarray, options: ScaleFactorOptions,
                  resolution_dps2: float) -> tuple[dict[str, np.ndarray], int]:
    """Cross-validation table over the options' orders and splits, and the order chosen."""
    table = polyfit.cross_validate(u, ref_dps2, max_order=options.orders[1],
                                   random_splits=options.random_splits, seed=options.seed,
                                   id_fraction=options.identification_fraction)
    low = options.orders[0]
    return table, polyfit.choose_order(table, min_order=low, abs_tol=resolution_dps2)


def calibrate(volts: np.ndarray, ref_dps2: np.ndarray, inflation: float = 1.0,
              options: ScaleFactorOptions | None = None, resolution_dps2: float = 0.0,
              ideal_line: Sequence[float] | np.ndarray | None = None) -> dict[str, Any]:
    """Cross-validated polynomial calibration of volts against a reference acceleration.

    ``options`` sets the orders scanned and the splits; ``resolution_dps2`` is the smallest
    RMSE gain that counts when choosing the order; ``ideal_line`` (intercept °/s², slope
    (°/s²)/V in u = volts − their mean) is the line L is measured from (default: this fit's
    own best straight line).
    """
    opts = options or ScaleFactorOptions()
    if np.std(ref_dps2) <= 0 or np.std(volts) <= 0:
        raise AnalysisError("scale factor: the reference or the sensor output is constant")
    v_mean = float(np.mean(volts))
    u = volts - v_mean
    table, order = _select_order(u, ref_dps2, opts, resolution_dps2)
    fit = polyfit.fit_polynomial(u, ref_dps2, order, inflation)
    line = polyfit.fit_polynomial(u, ref_dps2, 1, inflation)
    a0, a1 = line.coefficients
    cov = line.covariance
    scale = 1.0 / a1
    u_scale = float(np.sqrt(cov[1, 1])) / a1**2
    offset_v = v_mean - a0 / a1
    grad = np.array([-1.0 / a1, a0 / a1**2])  # ∂offset/∂(a0, a1)
    u_offset = float(np.sqrt(grad @ cov[:2, :2] @ grad))
    inverse = polyfit.fit_polynomial(ref_dps2, volts, order, inflation)
    lin = float(polyfit.nonlinearity(fit, float(u.min()), float(u.max())))
    ideal = line.coefficients if ideal_line is None else np.asarray(ideal_line)
    linearity_l = polyfit.linearity_l(fit, u, ideal)
    return {
        "scale_v_per_dps2": scale, "scale_u_v_per_dps2": u_scale,
        "scale_ci95": [scale - Z95 * u_scale, scale + Z95 * u_scale],
        "offset_v": offset_v, "offset_u_v": u_offset,
        "order": order, "rmse_dps2": fit.rmse, "coefficients": fit.coefficients.tolist(),
        "ci95": fit.ci95.tolist(), "fit": fit.summary(), "volts_mean_v": v_mean,
        "validation": {"rmse_dps2": table["rmse_validation"].mean(axis=1).tolist(),
                       "naic": table["naic"].mean(axis=1).tolist()},
        "nonlinearity_dps2": lin, "linearity_l_dps2": linearity_l,
        "inverse": {"order": order, "coefficients_v": inverse.coefficients.tolist(),
                    "ci95": inverse.ci95.tolist(), "rmse_v": inverse.rmse,
                    "note": "volts = Σ c_i·α^i, α in °/s²"},
    }


def _figure(volts: np.ndarray, ref: np.ndarray, result: dict[str, Any]) -> str:
    fig, ax = new_figure(2)
    step = max(volts.size // 800, 1)  # ~800 points keep the SVG small
    fit = np.polynomial.polynomial.polyval(volts - result["volts_mean_v"],
                                           result["coefficients"])
    ax[0, 0].plot(volts[::step], ref[::step], ".", ms=1, label="data", rasterized=True)
    ax[0, 0].plot(volts[::step], fit[::step], "-", lw=0.8, label=f"order {result['order']}")
    ax[0, 0].set(xlabel="sensor output / V", ylabel="reference / (°/s²)")
    ax[0, 0].legend(fontsize=7)
    ax[1, 0].plot(ref[::step], (ref - fit)[::step], ".", ms=1, rasterized=True)
    ax[1, 0].set(xlabel="reference / (°/s²)", ylabel="residual / (°/s²)")
    tight_layout(fig)
    return to_svg(fig)


def _ideal_line(chosen: Sequence[SyncedStep], sensor: SensorInfo, v_mean: float
                ) -> np.ndarray:
    """The study's ideal line g (Eq. 3.36): the least-squares line of the table's own
    acceleration estimate on the volts, (intercept, slope) in u = volts − ``v_mean``."""
    parts = [aligned_pair(s, sensor, "table_estimate") for s in chosen]
    volts = np.concatenate([p[0] for p in parts])
    ref = np.concatenate([p[1] for p in parts])
    return np.asarray(np.polynomial.polynomial.polyfit(volts - v_mean, ref, 1))


def calibrate_steps(chosen: Sequence[SyncedStep], sensor: SensorInfo,
                    options: ScaleFactorOptions) -> tuple[dict[str, Any], str]:
    """Calibration values and figure of one sensor from the records of one level."""
    reference = options.reference
    parts = [aligned_pair(s, sensor, reference) for s in chosen]
    volts = np.concatenate([p[0] for p in parts])
    ref = np.concatenate([p[1] for p in parts])
    if reference == "smoothed":  # residuals band-limited by the reference's known corner
        inflation = chosen[0].sample_rate_hz / (2.0 * max(SMOOTHED_CORNER_HZ, parts[0][3]))
    else:
        inflation = correlation_inflation(ref - _line(volts, ref))
    result = calibrate(volts, ref, inflation, options, RESOLUTION_FR * sensor.range_dps2,
                       _ideal_line(chosen, sensor, float(np.mean(volts))))
    dev_pct = 100.0 * (result["scale_v_per_dps2"] / sensor.nominal_scale_v_per_dps2 - 1.0)
    result |= {
        "reference": reference, "alignment_delay_s": float(np.mean([p[2] for p in parts])),
        "steps": [s.step.id for s in chosen], "scale_deviation_pct": dev_pct,
        "nonlinearity_pct_fr": 100.0 * result["nonlinearity_dps2"] / (2 * sensor.range_dps2),
    }
    return result, _figure(volts, ref, result)


def sensor_levels(steps: Sequence[SyncedStep], sensor: SensorInfo, options: ScaleFactorOptions
                  ) -> tuple[dict[str, Any], str] | None:
    """The channel's headline calibration with every level and the linearity, and the
    headline's figure; None without a candidate step."""
    groups = level_groups(calibration_candidates(steps, sensor))
    if not groups:
        return None
    done: dict[Level, dict[str, Any]] = {}
    figures: dict[Level, str] = {}
    for (accel, temp), chosen in groups.items():
        result, figures[(accel, temp)] = calibrate_steps(chosen, sensor, options)
        done[(accel, temp)] = result | {
            "accel_dps2": accel, "temperature_c": temp,
            "frequency_hz": float(chosen[0].step.frequency_hz or 0.0)}
    top = headline_level(list(done))
    headline = dict(done[top])
    headline["levels"] = [dict(r) for r in done.values()]
    headline["linearity"] = linearity(done, top[1], sensor.range_dps2)
    return headline, figures[top]


class ScaleFactorAnalysis:
    """Polynomial scale-factor calibration of every sensor with a suitable sine step, at every
    acceleration level (and set-point), with the linearity across the levels."""

    key: ClassVar[str] = "scale_factor"
    requires: ClassVar[tuple[str, ...]] = ("sync",)
    #: what the plan must hold (checked by ``validate``; aatest.engine.requirements)
    requirements: ClassVar[tuple[Requirement, ...]] = needs.SCALE_FACTOR
    #: the acceptance quantities it produces (judged when it is listed)
    #: (the non-linearity is judged where it is measured — two or more levels, or a curved
    #: model — and asked for by a procedure limit or ``judge``; one level resolves none)
    judges: ClassVar[tuple[str, ...]] = ("scale_factor_deviation_pct",)
    #: what it measures when the data allow, judged only when produced or asked for
    also_measures: ClassVar[tuple[str, ...]] = ("nonlinearity_pct_fr",)
    Options: ClassVar[type[ScaleFactorOptions]] = ScaleFactorOptions
    Result: ClassVar[type[ScaleFactorResult]] = ScaleFactorResult

    def applies_to(self, data: Dataset) -> bool:
        return any(s.step.kind == "sine" for s in data.steps)

    def run(self, data: Dataset, context: AnalysisContext) -> AnalysisOutput[ScaleFactorResult]:
        steps = steps_of(context)
        options = options_of(context, ScaleFactorOptions)
        values: dict[str, Any] = {}
        figures: dict[str, str] = {}
        for sensor in data.sensors:
            out = sensor_levels(steps, sensor, options)
            if out is not None:
                values[sensor.channel], figures[f"scale_factor_{sensor.channel}"] = out
        return AnalysisOutput(ScaleFactorResult.model_validate(values), figures)
