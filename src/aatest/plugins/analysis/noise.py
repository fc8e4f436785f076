"""Output noise of the sensors at rest: PSD, band RMS and Allan deviation (docs/method.md §1.3).

From the static steps: Welch PSD of the output (V²/Hz), RMS in the datasheet band DC–400 Hz
(mean removed) against the datasheet limit, and the overlapping Allan deviation of the output
expressed in °/s² (allantools, frequency data) on the longest record, with the usual noise
terms read off the log-log curve: white noise N (slope −½, σ·√τ), bias instability B
(flat minimum / 0.664) and random walk K (slope +½, σ/√(τ/3)).

The ``drift`` analysis (:class:`DriftAnalysis`) reads a long static record (hours, streamed by
the DAQ): the 2 kHz output averaged to 1 s, its bias drift (slope V/h, peak-to-peak, bias and
temperature per 30 min) and the Allan deviation to τ ≥ 1000 s with N, B and K fitted.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np
from pydantic import BaseModel, ConfigDict, Field
from scipy import signal

from aatest.engine.dataset import Dataset, LazySteps, SensorInfo
from aatest.engine.errors import AnalysisError
from aatest.engine.interfaces import AnalysisContext, AnalysisOutput
from aatest.engine.logs import SampledLog
from aatest.plugins.analysis._common import new_figure, options_of, scale_in_use, steps_of, to_svg
from aatest.results.noise import DriftResult, NoiseResult
from aatest.sync.freeze_pulse import SyncedStep

BAND_HZ = 400.0
_SLOPE_TOL = 0.15
#: points needed to read local log-log slopes off an Allan curve
_MIN_SLOPE_POINTS = 3


def band_rms(volts: np.ndarray, fs_hz: float, band_hz: float = BAND_HZ
             ) -> tuple[float, np.ndarray, np.ndarray]:
    """RMS (V) of the mean-removed output between DC and ``band_hz``, with the Welch PSD."""
    nperseg = int(min(volts.size, 2**13))
    f, psd = signal.welch(np.asarray(volts, dtype=float) - np.mean(volts), fs=fs_hz,
                          nperseg=nperseg, detrend="constant")
    inband = f <= band_hz
    return float(np.sqrt(np.trapezoid(psd[inband], f[inband]))), f, psd


def allan_terms(rate: np.ndarray, fs_hz: float) -> dict[str, Any]:
    """Overlapping Allan deviation of a rate-like signal and its noise terms."""
    import allantools

    taus, adev = allantools.oadev(np.asarray(rate, dtype=float), rate=fs_hz,
                                  data_type="freq", taus="octave")[:2]
    return allan_terms_of(np.asarray(taus, float), np.asarray(adev, float))


def sensor_noise(steps: Sequence[SyncedStep], sensor: SensorInfo, scale_v_per_dps2: float,
                 band_hz: float = BAND_HZ) -> tuple[dict[str, Any], str]:
    """Noise figures of one sensor over its static steps, and the PSD/Allan figure."""
    fs = steps[0].sample_rate_hz
    rms = [band_rms(s.daq[sensor.channel], fs, band_hz)[0] for s in steps]
    longest = max(steps, key=len)
    volts = np.asarray(longest.daq[sensor.channel], dtype=float)
    _, f, psd = band_rms(volts, fs, band_hz)
    allan = allan_terms((volts - volts.mean()) / scale_v_per_dps2, fs)
    worst = float(max(rms))
    values = {"rms_v": float(np.mean(rms)), "rms_max_v": worst, "rms_per_step_v": rms,
              "rms_dps2": float(np.mean(rms)) / scale_v_per_dps2, "band_hz": band_hz,
              "scale_v_per_dps2_used": scale_v_per_dps2,
              "psd_floor_v_per_sqrt_hz": float(np.sqrt(np.median(psd[(f > 1) & (f < band_hz)]))),
              "allan_dps2": allan, "record_step": longest.step.id}
    fig, ax = new_figure(2, height_in=2.4)
    ax[0, 0].loglog(f[1:], np.sqrt(psd[1:]), lw=0.6, rasterized=True)
    ax[0, 0].set(xlabel="frequency / Hz", ylabel="V/√Hz", title=f"noise {sensor.channel}")
    ax[1, 0].loglog(allan["tau_s"], allan["adev"], "o-", ms=3)
    ax[1, 0].set(xlabel="τ / s", ylabel="Allan dev. / (°/s²)")
    fig.tight_layout()
    return values, to_svg(fig)


class NoiseOptions(BaseModel):
    """The band the output RMS is integrated over (the datasheet's: DC–400 Hz)."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    band_hz: float = Field(BAND_HZ, gt=0, description="upper band edge, Hz")


class NoiseAnalysis:
    """PSD, DC–400 Hz RMS and Allan deviation of every sensor from the static records.

    Requires ``scale_factor`` as well as ``sync``: the noise in °/s² (and the Allan terms) use
    the calibrated scale factor when the run calibrated one, else the datasheet's.
    """

    key: ClassVar[str] = "noise"
    requires: ClassVar[tuple[str, ...]] = ("sync", "scale_factor")
    Options: ClassVar[type[NoiseOptions]] = NoiseOptions
    Result: ClassVar[type[NoiseResult]] = NoiseResult

    def applies_to(self, data: Dataset) -> bool:
        return any(s.step.kind == "static" for s in data.steps)

    def run(self, data: Dataset, context: AnalysisContext) -> AnalysisOutput[NoiseResult]:
        static = steps_of(context, "static")
        band_hz = options_of(context, NoiseOptions).band_hz
        values: dict[str, Any] = {}
        figures: dict[str, str] = {}
        for sensor in data.sensors:
            values[sensor.channel], figures[f"noise_{sensor.channel}"] = sensor_noise(
                static, sensor, scale_in_use(context, sensor), band_hz)
        return AnalysisOutput(NoiseResult.model_validate(values), figures)


# --- long static records: bias drift and the Allan deviation to τ ≥ 1000 s --------------------

#: the bias peak-to-peak is taken over means of this length, s (white noise averaged out)
_PEAK_TO_PEAK_WINDOW_S = 60.0
#: first reduction stage of a long record, s (block means at 20 Hz)
_STAGE_S = 0.05
#: an Allan-fit term below this share of the variance at every τ is reported as absent
_MIN_TERM_SHARE = 1e-3
#: a 0/1 logic channel is high above this level
_LOGIC_HIGH = 0.5
#: fewest averaged values a drift fit and an Allan curve are made from
_MIN_MEANS = 4
#: minimum clusters at the longest τ of a reported Allan deviation (oadev: τ ≤ T/2)
_MIN_CLUSTERS = 2


#: samples reduced per pass of :func:`block_means` (8 MB of float64: a bounded temporary)
_BLOCK_MEANS_CHUNK = 2**20


def block_means(values: np.ndarray, per_block: int, origin: float = 0.0) -> np.ndarray:
    """Means of consecutive non-overlapping blocks of ``per_block`` samples (any unit) of
    ``values − origin``; the incomplete tail is dropped.

    Vectorised over rows of a reshaped view, a bounded number of rows at a time: an hours-long
    record (or its time stamps less their first, ``origin``) is never copied whole. Each row's
    mean is computed exactly as on the whole array, so the result does not depend on the chunk.
    """
    whole = values.size // per_block
    out = np.empty(whole, dtype=float)
    rows = max(1, _BLOCK_MEANS_CHUNK // per_block)
    for first in range(0, whole, rows):
        last = min(whole, first + rows)
        part = np.asarray(values[first * per_block: last * per_block], dtype=float)
        if origin:
            part = part - origin
        out[first:last] = part.reshape(last - first, per_block).mean(1)
    return out


def reduce_rate(values: np.ndarray, fs_hz: float, average_s: float) -> np.ndarray:
    """The record reduced to one value per ``average_s`` s without aliasing (``fs_hz`` in Hz).

    A plain 1 s mean lets a narrow band near a rig line through its sinc sidelobes (the motor's
    35 Hz band: ≈1 % of several °/s², as large as the sensor's own white noise per second). So:
    means over :data:`_STAGE_S` (nulls at multiples of 20 Hz, what is left folds below 10 Hz),
    then a zero-phase FIR low-pass and decimation to ``average_s`` (scipy ``resample_poly``,
    its Kaiser-window filter), which removes the
    folded band and keeps the white-noise density below the new Nyquist frequency. Values in
    the input's unit; the incomplete tail is dropped.
    """
    from scipy.signal import resample_poly

    stage = max(1, round(min(_STAGE_S, average_s) * fs_hz))
    coarse = block_means(values, stage)
    factor = max(1, round(average_s * fs_hz / stage))
    if factor == 1:
        return coarse
    whole = coarse.size // factor * factor
    # the edges are padded along a fitted line, so a drifting record has no edge transient
    reduced = resample_poly(coarse[:whole], 1, factor, padtype="line")
    return np.asarray(reduced, dtype=float)


def fit_allan(taus_s: np.ndarray, adev: np.ndarray) -> dict[str, float | None]:
    """N, B, K, R of σ²(τ) = N²/τ + (0.664·B)² + K²·τ/3 + R²·τ²/2 by non-negative least squares
    on the Allan variance, each point weighted by 1/σ² (relative errors count alike).

    ``taus_s`` in s, ``adev`` in the rate-like unit u (°/s²): N in u·√s, B in u, K in u/√s,
    R (rate ramp: a steady drift) in u/s; a term the data do not support comes back None.
    """
    from scipy.optimize import nnls

    taus, var = np.asarray(taus_s, float), np.asarray(adev, float) ** 2
    names = ("white_noise_dps2_sqrt_s", "bias_instability_dps2",
             "rate_random_walk_dps2_per_sqrt_s", "rate_ramp_dps2_per_s")
    if taus.size < len(names):
        return dict.fromkeys(names)
    design = np.column_stack([1.0 / taus, np.ones_like(taus), taus / 3.0, taus**2 / 2.0])
    coef, _ = nnls(design / var[:, None], np.ones_like(taus))
    roots = np.sqrt(coef) * np.array([1.0, 1.0 / 0.664, 1.0, 1.0])
    # a term is supported when it makes at least 0.1 % of the variance somewhere on the curve
    share = (design * coef / var[:, None]).max(axis=0)
    return {name: float(root) if part > _MIN_TERM_SHARE else None
            for name, root, part in zip(names, roots, share, strict=True)}


def drift_of(time_s: np.ndarray, volts: np.ndarray, temperature_c: np.ndarray | None,
             fs_hz: float, scale_v_per_dps2: float, average_s: float,
             interval_s: float) -> dict[str, Any]:
    """Bias drift, interval table and Allan deviation of one channel at rest.

    The 2 kHz record (``volts``, V; ``time_s``, s, the logger's clock) is first reduced to one
    value per ``average_s`` s (:func:`reduce_rate`), then: least-squares line of the bias
    (V/h), peak-to-peak of its 60 s means (V), mean bias and ``temperature_c`` (°C) per
    ``interval_s`` s, and the overlapping Allan deviation (allantools, octave τ) of the means
    in °/s² (divided by ``scale_v_per_dps2``, V per °/s²) with its fitted noise terms.
    """
    import allantools

    per = max(1, round(average_s * fs_hz))
    tau0_s = per / fs_hz
    means_v = reduce_rate(volts, fs_hz, average_s)
    t_h = block_means(time_s, per, origin=time_s[0])[: means_v.size] / 3600.0
    if means_v.size < _MIN_MEANS:
        raise AnalysisError(f"record of {volts.size} samples is too short for a drift fit "
                            f"at {average_s} s averaging")
    (slope, intercept), cov = np.polyfit(t_h, means_v, 1, cov=True)
    window = max(1, round(_PEAK_TO_PEAK_WINDOW_S / tau0_s))
    smooth = block_means(means_v, window) if means_v.size >= 2 * window else means_v
    rate = (means_v - means_v.mean()) / scale_v_per_dps2
    taus, adev = allantools.oadev(rate, rate=1.0 / tau0_s, data_type="freq", taus="octave")[:2]
    taus, adev = np.asarray(taus, float), np.asarray(adev, float)
    keep = taus * _MIN_CLUSTERS <= rate.size * tau0_s
    taus, adev = taus[keep], adev[keep]
    per_interval = max(1, round(interval_s / tau0_s))
    starts = np.arange(0, means_v.size, per_interval)
    temps = (block_means(temperature_c, per)[: means_v.size] if temperature_c is not None
             else None)
    intervals = [{"start_h": float(t_h[i]), "bias_v": float(means_v[i:i + per_interval].mean()),
                  "temperature_c": float(temps[i:i + per_interval].mean())
                  if temps is not None else None} for i in starts]
    return {
        "duration_s": float(volts.size / fs_hz), "average_s": tau0_s,
        "bias_v": float(means_v.mean()), "drift_v_per_h": float(slope),
        "drift_sigma_v_per_h": float(np.sqrt(cov[0, 0])),
        "drift_dps2_per_h": float(slope) / scale_v_per_dps2,
        "peak_to_peak_v": float(np.ptp(smooth)), "scale_v_per_dps2_used": scale_v_per_dps2,
        "allan_dps2": allan_terms_of(taus, adev), "allan_fit": fit_allan(taus, adev),
        "max_tau_s": float(taus.max()) if taus.size else 0.0, "intervals": intervals,
        "_intercept_v": float(intercept),
    }


def allan_terms_of(taus: np.ndarray, adev: np.ndarray) -> dict[str, Any]:
    """:func:`allan_terms` read off an already computed Allan deviation (τ in s)."""
    slope = (np.gradient(np.log(adev), np.log(taus)) if taus.size >= _MIN_SLOPE_POINTS
             else np.zeros_like(taus))
    white = np.abs(slope + 0.5) < _SLOPE_TOL
    walk = np.abs(slope - 0.5) < _SLOPE_TOL
    return {
        "tau_s": taus.tolist(), "adev": adev.tolist(),
        "white_noise_per_sqrt_hz": float(np.median(adev[white] * np.sqrt(taus[white])))
        if white.any() else None,
        "bias_instability": float(adev.min() / 0.664) if adev.size else None,
        "random_walk": float(np.median(adev[walk] / np.sqrt(taus[walk] / 3.0)))
        if walk.any() else None,
    }


def drift_figure(channel: str, values: dict[str, Any], t_h: np.ndarray,
                 means_v: np.ndarray) -> str:
    """Bias against time with its fitted line, and the Allan deviation (SVG)."""
    fig, ax = new_figure(2, height_in=2.4)
    ax[0, 0].plot(t_h, means_v, lw=0.5, rasterized=True)
    ax[0, 0].plot(t_h, values["_intercept_v"] + values["drift_v_per_h"] * t_h, "k--", lw=0.8)
    ax[0, 0].set(xlabel="time / h", ylabel="bias / V", title=f"bias drift {channel}")
    allan = values["allan_dps2"]
    ax[1, 0].loglog(allan["tau_s"], allan["adev"], "o-", ms=3)
    ax[1, 0].set(xlabel="τ / s", ylabel="Allan dev. / (°/s²)")
    fig.tight_layout()
    return to_svg(fig)


class DriftOptions(BaseModel):
    """How the long record is reduced and reported."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    average_s: float = Field(1.0, gt=0, description="averaging interval before the Allan "
                             "deviation and the drift fit, s")
    temperature_every_s: float = Field(1800.0, gt=0, description="bias and temperature are "
                                       "reported per interval of this length, s")


class DriftAnalysis:
    """Bias drift and Allan deviation (to τ ≥ 1000 s on a 2 h record) of every sensor, from
    the longest static record, read straight from the DAQ log.

    Needs no synchronisation (a long record's table log holds snapshots only) and uses the
    datasheet scale factor for the °/s² figures (a drift test calibrates no scale factor).
    """

    key: ClassVar[str] = "drift"
    requires: ClassVar[tuple[str, ...]] = ()
    Options: ClassVar[type[DriftOptions]] = DriftOptions
    Result: ClassVar[type[DriftResult]] = DriftResult

    def applies_to(self, data: Dataset) -> bool:
        return any(s.step.kind == "static" for s in data.steps)

    def run(self, data: Dataset, context: AnalysisContext) -> AnalysisOutput[DriftResult]:
        found = _drift_per_sensor(data, options_of(context, DriftOptions))
        # drawn once the record is released: matplotlib's text parser keeps exceptions whose
        # tracebacks reach the caller's frames, which would hold the record until a gc pass
        figures = {f"drift_{channel}": drift_figure(channel, values, t_h, means_v)
                   for channel, (values, t_h, means_v) in found.items()}
        values = {channel: {k: v for k, v in entry.items() if k != "_intercept_v"}
                  for channel, (entry, _, _) in found.items()}
        return AnalysisOutput(DriftResult.model_validate(values), figures)


def _drift_per_sensor(data: Dataset, options: DriftOptions
                      ) -> dict[str, tuple[dict[str, Any], np.ndarray, np.ndarray]]:
    """Per sensor channel: the :func:`drift_of` values of the longest static record, its time
    (h) and its 1 s means (V) for the figure. The decoded record lives only in this call."""
    step_id, daq = longest_static_record(data)
    record = _after_trigger(daq)
    temperature = daq.channels.get("temperature_c")
    time_s = daq.time_s[record]
    per = max(1, round(options.average_s * daq.sample_rate_hz))
    found = {}
    for sensor in data.sensors:
        volts = daq[sensor.channel][record]
        values = drift_of(time_s, volts, temperature[record] if temperature is not None else None,
                          daq.sample_rate_hz, float(sensor.nominal_scale_v_per_dps2),
                          options.average_s, options.temperature_every_s)
        means_v = reduce_rate(volts, daq.sample_rate_hz, options.average_s)
        t_h = block_means(time_s, per, origin=time_s[0])[: means_v.size] / 3600.0
        found[sensor.channel] = ({**values, "record_step": step_id}, t_h, means_v)
    return found


def longest_static_record(data: Dataset) -> tuple[str, SampledLog]:
    """``(step id, DAQ log)`` of the longest static step: the sensor channels, the trigger and
    ``temperature_c`` (and the time stamps) only.

    Why: a 2 h record at 2 kHz is 115 MB per channel. The step is chosen by the sample count
    its record gives (nothing decoded), and only the channels the drift reads are decoded (the
    lazy dataset's partial decode); an in-memory dataset is read as it is.
    """
    static = [i for i, step in enumerate(data.planned) if step.kind == "static"]
    if not static:
        raise AnalysisError("no static step to read a drift record from")
    steps = data.steps
    index = max(static, key=lambda i: steps[i].samples("daq"))  # first of equal lengths
    if not isinstance(steps, LazySteps):
        return steps[index].step.id, steps[index].daq
    wanted = [s.channel for s in data.sensors] + ["trigger", "temperature_c"]
    return steps.planned[index].id, steps.partial(index, {"daq": wanted}).daq


def _after_trigger(daq: Any) -> slice:
    """The DAQ samples from the trigger on (the record proper, without the logger's lead)."""
    trigger = daq.channels.get("trigger")
    if trigger is None:
        return slice(None)
    on = np.flatnonzero(np.asarray(trigger) > _LOGIC_HIGH)
    return slice(int(on[0]) if on.size else 0, None)
