"""Which logger chain the nominal replay assumes: the pre-sample filter and the converter.

The documented rig's sensor logger has a 100 Hz 2nd-order pre-sample filter (docs/method.md §1.3);
data from other tools may have none. The data's model file decides when it exists; otherwise
the residual noise does, because the filter shapes the sensor noise it records.

The converter (input range and bits, so its step q) is the logger the data state: the rig
description's ``instruments.logger`` recorded with them, else the data's rig model, else the
stated default (±10 V, 16 bit). Its step bounds what the data can attribute to the sensor: a
waveform error smaller than the converter's own rounding is not the sensor's.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy import signal

from aatest.diagnose.alignment import nominal_fit
from aatest.diagnose.candidates.base import Context
from aatest.diagnose.design import predict
from aatest.diagnose.replay import Replay
from aatest.diagnose.spec import ChannelInfo
from aatest.engine.rig_description import LoggerSpec
from aatest.metrology.logger_rails import converter_of
from aatest.numerics import TINY
from aatest.recording.dataset import Dataset
from aatest.twin.daq import antialias_filter

#: the logger pre-sample filter of the documented rig (docs/method.md §1.3), tried when unstated
DEFAULT_ANTIALIAS_HZ = 100.0
#: residual noise PSD ratio (high band / low band) below which the noise is filtered
ROLLOFF_RATIO = 0.5
#: |ln(fc / 100 Hz)| below which a fitted corner is the documented filter (≈ 3 standard
#: deviations of the estimate from two 4096-sample records at rest)
SAME_CORNER_LOG = 0.05
#: corners tried (log grid from 1 % to 40 % of the sample rate) before the Brent refinement
_CORNER_GRID = 61
#: re-weighting passes of the Whittle fit of the noise levels
_WHITTLE_ITER = 6
#: a PSD bin beyond this quantile of the averaged-periodogram spread is a line, not noise
_LINE_QUANTILE = 0.999
#: bins either side of a line bin dropped with it (Hann main lobe ±2 bins, first sidelobe)
_LINE_SKIRT_BINS = 3
#: passes of line trimming (each re-fits the corner on the bins left)
_TRIM_PASSES = 5
#: fewest PSD bins a corner is fitted on
_MIN_BINS = 16


def channel_info(dataset: Dataset, channel: str, corner: float | None, t_ref_c: float
                 ) -> ChannelInfo:
    """Design inputs of one channel (axis, range, logger filter, T_ref)."""
    s = dataset.sensor(channel)
    return ChannelInfo(channel, s.axis, s.range_dps2, corner, t_ref_c, s.nominal_scale_v_per_dps2)


def targets_of(replay: Replay, channel: str) -> dict[int, np.ndarray]:
    """Measured volts of ``channel`` per step."""
    return {s.index: s.volts[channel] for s in replay.steps}


def stated_antialias(dataset: Dataset) -> tuple[bool, float | None]:
    """(stated?, corner Hz) of the logger's pre-sample filter from the data's model, if any."""
    model = dataset.metadata.get("model")
    if isinstance(model, dict) and isinstance(model.get("daq"), dict):
        daq = model["daq"]
        if "antialias_hz" in daq:
            return True, daq["antialias_hz"]
        return True, DEFAULT_ANTIALIAS_HZ
    path = dataset.metadata.get("model_file")
    if isinstance(path, str):
        from aatest.twin.model import load_rig_model

        # an unreadable or invalid model file is the dataset's error (ProcedureError naming its
        # file, line and field), not a logger without a stated filter
        rig = load_rig_model(Path(str(dataset.source)) / path)  # imports are local files
        if "daq" in rig.model_fields_set:  # a sensor-only model file states no logger
            return True, rig.daq.antialias_hz
    return False, None


def stated_converter(dataset: Dataset) -> tuple[LoggerSpec, str]:
    """(converter, where it is stated) of the sensor logger the data were recorded with
    (:func:`aatest.metrology.logger_rails.converter_of` of the data's metadata): the rig
    description's ``instruments.logger``, else the data's rig model, else the stated default
    logger (±10 V, 16 bit)."""
    return converter_of(dataset.metadata)


def residual_noise_psd(ctx: Context, at_rest: bool = False
                       ) -> tuple[np.ndarray, np.ndarray, int]:
    """(f Hz, PSD V²/Hz, Welch segments averaged) of the nominal replay's residual.

    ``at_rest``: steps at rest only, when there are any. There the residual is the recorded
    noise alone, whereas an unexplained effect on a moving step (clipping, hysteresis, table
    ripple) puts harmonics of the motion into the band and bends the noise shape like a filter.
    """
    from aatest.diagnose.candidates.logger import WELCH_SEGMENT, residual_psd

    fit = nominal_fit(ctx)
    pred = predict(ctx.replay, ctx.info, fit)
    still = {s.index for s in ctx.replay.steps
             if at_rest and not (s.inner.moving or s.outer.moving)}
    residuals = {i: ctx.targets[i] - pred[i] for i in pred if not still or i in still}
    segments = sum((r.size - WELCH_SEGMENT) // (WELCH_SEGMENT // 2) + 1
                   for r in residuals.values() if r.size >= WELCH_SEGMENT)
    freq, psd = residual_psd(ctx, residuals)
    return freq, psd, segments


def noise_rolloff(freq: np.ndarray, psd: np.ndarray, fs: float) -> float:
    """Residual PSD far above a filter corner over the PSD below it (1 = white noise).

    A logger's pre-sample filter shapes the sensor noise it records; the ratio says whether the
    data carry that shape, whatever the signal errors at the (≤ 10 Hz) excitation.
    """
    low = (freq >= 0.01 * fs) & (freq <= 0.03 * fs)
    high = (freq >= 0.2 * fs) & (freq <= 0.45 * fs)
    if not low.any() or not high.any():
        return 1.0
    return float(np.median(psd[high]) / max(np.median(psd[low]), TINY))


def _noise_model(h2: np.ndarray, p: np.ndarray, use: np.ndarray | None = None
                 ) -> tuple[np.ndarray, float]:
    """(model PSD, Whittle negative log-likelihood) of p ≈ s²·h2 + e², s², e² ≥ 0 by ML
    (fitted on the bins ``use``, all by default; the model is returned on every bin).

    A Welch PSD ordinate is a scaled χ² variable about its mean m, so the likelihood of the
    spectrum is Π exp(−p/m)/m (Whittle); for a mean linear in (s², e²) its maximum is found
    by iteratively re-weighted non-negative least squares (weights 1/m).
    """
    from scipy.optimize import nnls

    x_all = np.column_stack([h2, np.ones_like(h2)])
    keep = np.ones(p.size, dtype=bool) if use is None else use
    x, y = x_all[keep], p[keep]
    m = y.copy()
    coef = np.zeros(2)
    for _ in range(_WHITTLE_ITER):
        coef, _ = nnls(x / m[:, None], y / m)
        m = np.maximum(x @ coef, TINY)
    return np.maximum(x_all @ coef, TINY), float(np.sum(np.log(m) + y / m))


def _filter_h2(fc: float, f: np.ndarray, fs: float) -> np.ndarray:
    b, a, _gain = antialias_filter(float(fc), round(1.0 / fs, 15))
    return np.asarray(np.abs(signal.freqz(b, a, worN=f, fs=fs)[1]) ** 2)


def _ml_corner(f: np.ndarray, p: np.ndarray, fs: float) -> float:
    """The corner (Hz) maximising the Whittle likelihood (log grid, then Brent)."""
    from scipy.optimize import minimize_scalar

    def nll(log_fc: float) -> float:
        return _noise_model(_filter_h2(float(np.exp(log_fc)), f, fs), p)[1]

    grid = np.log(np.geomspace(0.01 * fs, 0.4 * fs, _CORNER_GRID))
    costs = np.array([nll(g) for g in grid])
    i = int(np.argmin(costs))
    res = minimize_scalar(nll, bounds=(grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]),
                          method="bounded", options={"xatol": 1e-4})
    return float(np.exp(res.x))


def estimate_corner_hz(freq: np.ndarray, psd: np.ndarray, fs: float, segments: int = 1) -> float:
    """Corner of a 2nd-order Butterworth pre-sample filter from the shape of the noise PSD.

    PSD(f) ≈ s²·|H(f; fc)|² + e² (filtered sensor noise plus white excess), H the bilinear
    discretisation the chain uses (its zero at Nyquist matters up there). fc, s², e² maximise
    the Whittle likelihood of the spectrum — the efficient estimator for averaged
    periodograms (a median log misfit scattered the corner by ±5 % on two short records, and
    a 5 % corner error is a 0.1 ms lag: a spurious jerk or delay once latch times resolve the
    alignment). Spectral lines are not noise (mains pickup, a motor line, harmonics of a
    clipped or backlashed sine): bins beyond the 99.9 % point of the χ² spread of
    ``segments`` averaged Welch segments are dropped and the corner re-fitted once.
    """
    from scipy import stats

    band = (freq >= 0.005 * fs) & (freq <= 0.45 * fs) & (psd > 0)
    f, p = freq[band], psd[band]
    if f.size < _MIN_BINS:
        return DEFAULT_ANTIALIAS_HZ
    k = max(segments, 1)
    limit = float(stats.gamma.ppf(_LINE_QUANTILE, a=k, scale=1.0 / k))
    noise = np.ones(f.size, dtype=bool)
    for _ in range(_TRIM_PASSES):  # a strong line bends the first fit: trim until none is left
        fc = _ml_corner(f[noise], p[noise], fs)
        model = _noise_model(_filter_h2(fc, f, fs), p, noise)[0]
        lines = noise & (p / model > limit)
        if not lines.any():
            break
        # a line leaks into its window's main lobe and first sidelobes: drop those bins too
        near = np.convolve(lines, np.ones(2 * _LINE_SKIRT_BINS + 1), mode="same") > 0
        if (noise & ~near).sum() < _MIN_BINS:
            break
        noise &= ~near
    # within the estimate's resolution of the documented rig's filter: take the documented value
    return (DEFAULT_ANTIALIAS_HZ if abs(np.log(fc / DEFAULT_ANTIALIAS_HZ)) < SAME_CORNER_LOG
            else round(fc, 1))


def logger_options(dataset: Dataset, replay: Replay) -> list[tuple[float | None, str]]:
    """Candidate logger filters of the nominal chain, with the reason: one when decided.

    Stated by the data's model, else read from the residual noise: a roll-off means the rig's
    pre-sample filter. White noise is ambiguous — no filter, or a filter drowned by excess
    white noise (a 2nd-order filter's lag looks like a 2.25 ms delay below 10 Hz) — so both
    chains are diagnosed and the one needing fewer effects wins (Occam).
    """
    stated, corner = stated_antialias(dataset)
    if stated:
        return [(corner, "stated by the data's model")]
    channel = replay.channels[0]
    targets = targets_of(replay, channel)
    contexts = {opt: Context(replay, channel_info(dataset, channel, opt, replay.t_ref_c), targets,
                             None)  # type: ignore[arg-type]
                for opt in (DEFAULT_ANTIALIAS_HZ, None)}
    # whether there is a roll-off, and where its corner is: steps at rest (the noise alone)
    freq, psd, segments = residual_noise_psd(contexts[DEFAULT_ANTIALIAS_HZ], at_rest=True)
    fs = 1.0 / replay.dt_s
    ratio = noise_rolloff(freq, psd, fs)
    if ratio < ROLLOFF_RATIO:
        corner = estimate_corner_hz(freq, psd, fs, segments)
        return [(corner, f"the residual noise rolls off like a 2nd-order filter at {corner:g} Hz "
                         f"(high/low band ratio {ratio:.3f})")]
    reason = (f"white residual noise (ratio {ratio:.2f}): no filter, or one drowned by excess "
              "noise; the simpler diagnosis decides")
    return [(None, reason), (DEFAULT_ANTIALIAS_HZ, reason)]
