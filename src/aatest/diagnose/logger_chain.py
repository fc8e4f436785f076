"""Which logger chain the nominal replay assumes: the pre-sample filter question.

The documented rig's sensor logger has a 100 Hz 2nd-order pre-sample filter (docs/method.md §1.3);
data from other tools may have none. The data's model file decides when it exists; otherwise
the residual noise does, because the filter shapes the sensor noise it records.
"""

from __future__ import annotations

import numpy as np
from scipy import signal

from aatest.diagnose.alignment import nominal_fit
from aatest.diagnose.design import ChannelInfo, predict
from aatest.diagnose.effects.base import Context
from aatest.diagnose.replay import Replay
from aatest.engine.dataset import Dataset
from aatest.twin.daq import antialias_filter

#: the logger pre-sample filter of the documented rig (docs/method.md §1.3), tried when unstated
DEFAULT_ANTIALIAS_HZ = 100.0
#: residual noise PSD ratio (high band / low band) below which the noise is filtered
ROLLOFF_RATIO = 0.5
#: |ln(fc / 100 Hz)| below which a fitted corner is the documented filter (the grid's step)
SAME_CORNER_LOG = 0.05


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
        try:
            from aatest.twin.model import load_rig_model

            rig = load_rig_model(dataset.source / path)
            return True, rig.daq.antialias_hz
        except Exception:  # noqa: BLE001 - a sensor-only model file states no logger
            return False, None
    return False, None


def residual_noise_psd(ctx: Context, at_rest: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(f Hz, PSD V²/Hz) of the nominal replay's residual, averaged over steps.

    ``at_rest``: steps at rest only, when there are any. There the residual is the recorded
    noise alone, whereas an unexplained effect on a moving step (clipping, hysteresis) puts
    harmonics of the excitation into the band the roll-off test reads and looks like a filter.
    """
    from aatest.diagnose.effects.logger import residual_psd

    fit = nominal_fit(ctx)
    pred = predict(ctx.replay, ctx.info, fit)
    still = {s.index for s in ctx.replay.steps
             if at_rest and not (s.inner.moving or s.outer.moving)}
    return residual_psd(ctx, {i: ctx.targets[i] - pred[i] for i in pred
                              if not still or i in still})


def noise_rolloff(freq: np.ndarray, psd: np.ndarray, fs: float) -> float:
    """Residual PSD far above a filter corner over the PSD below it (1 = white noise).

    A logger's pre-sample filter shapes the sensor noise it records; the ratio says whether the
    data carry that shape, whatever the signal errors at the (≤ 10 Hz) excitation.
    """
    low = (freq >= 0.01 * fs) & (freq <= 0.03 * fs)
    high = (freq >= 0.2 * fs) & (freq <= 0.45 * fs)
    if not low.any() or not high.any():
        return 1.0
    return float(np.median(psd[high]) / max(np.median(psd[low]), 1e-300))


def estimate_corner_hz(freq: np.ndarray, psd: np.ndarray, fs: float) -> float:
    """Corner of a 2nd-order Butterworth pre-sample filter from the shape of the noise PSD.

    PSD(f) ≈ s²·|H(f; fc)|² + e² (filtered sensor noise plus white excess), H the bilinear
    discretisation the chain uses (its zero at Nyquist matters up there); for each fc on a
    log grid s² and e² follow by non-negative least squares in the log-weighted sense; the fc
    with the smallest log-spectral misfit wins.
    """
    from scipy.optimize import nnls

    band = (freq >= 0.005 * fs) & (freq <= 0.45 * fs) & (psd > 0)
    f, p = freq[band], psd[band]
    best = (np.inf, DEFAULT_ANTIALIAS_HZ)
    for fc in np.geomspace(0.01 * fs, 0.4 * fs, 121):
        b, a, _gain = antialias_filter(float(fc), round(1.0 / fs, 15))
        h2 = np.abs(signal.freqz(b, a, worN=f, fs=fs)[1]) ** 2
        coef, _ = nnls(np.column_stack([h2, np.ones_like(f)]) / p[:, None], np.ones_like(f))
        model = coef[0] * h2 + coef[1]
        if model.min() <= 0:
            continue
        misfit = float(np.median(np.abs(np.log(p / model))))
        if misfit < best[0]:
            best = (misfit, float(fc))
    fc = best[1]
    # within the grid's resolution of the documented rig's filter: take the documented value
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
    # whether there is a roll-off: steps at rest; where its corner is: all steps (more data)
    freq, psd = residual_noise_psd(contexts[DEFAULT_ANTIALIAS_HZ], at_rest=True)
    fs = 1.0 / replay.dt_s
    ratio = noise_rolloff(freq, psd, fs)
    if ratio < ROLLOFF_RATIO:
        corner = estimate_corner_hz(*residual_noise_psd(contexts[DEFAULT_ANTIALIAS_HZ]), fs)
        return [(corner, f"the residual noise rolls off like a 2nd-order filter at {corner:g} Hz "
                         f"(high/low band ratio {ratio:.3f})")]
    reason = (f"white residual noise (ratio {ratio:.2f}): no filter, or one drowned by excess "
              "noise; the simpler diagnosis decides")
    return [(None, reason), (DEFAULT_ANTIALIAS_HZ, reason)]
