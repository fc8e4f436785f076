"""Which logger chain the nominal replay assumes: the pre-sample filter question.

The documented rig's sensor logger has a 100 Hz 2nd-order pre-sample filter (method.md §1.3);
data from other tools may have none. The data's model file decides when it exists; otherwise
the residual noise does, because the filter shapes the sensor noise it records.
"""

from __future__ import annotations

import numpy as np

from aatest.engine.dataset import Dataset
from aatest.plugins.diagnose.design import ChannelInfo, predict
from aatest.plugins.diagnose.effects.base import Context
from aatest.plugins.diagnose.replay import Replay
from aatest.plugins.diagnose.alignment import nominal_fit

#: the logger pre-sample filter of the documented rig (method.md §1.3), tried when unstated
DEFAULT_ANTIALIAS_HZ = 100.0
#: residual noise PSD ratio (high band / low band) below which the noise is filtered
ROLLOFF_RATIO = 0.5


def channel_info(dataset: Dataset, channel: str, corner: float | None, t_ref_c: float) -> ChannelInfo:
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
            from aatest.plugins.sim.model import load_rig_model

            rig = load_rig_model(dataset.source / path)
            return True, rig.daq.antialias_hz
        except Exception:  # noqa: BLE001 - a sensor-only model file states no logger
            return False, None
    return False, None


def noise_rolloff(ctx: Context) -> float:
    """Residual PSD far above the filter corner over the PSD below it (1 = white noise).

    A logger's pre-sample filter shapes the sensor noise it records; the ratio says whether the
    data carry that shape, whatever the signal errors at the (≤ 10 Hz) excitation.
    """
    from aatest.plugins.diagnose.effects.logger import residual_psd

    fit = nominal_fit(ctx)
    pred = predict(ctx.replay, ctx.info, fit)
    freq, psd = residual_psd(ctx, {i: ctx.targets[i] - pred[i] for i in pred})
    fs = 1.0 / ctx.replay.dt_s
    low = (freq >= 0.01 * fs) & (freq <= 0.03 * fs)
    high = (freq >= 0.2 * fs) & (freq <= 0.45 * fs)
    if not low.any() or not high.any():
        return 1.0
    return float(np.median(psd[high]) / max(np.median(psd[low]), 1e-300))


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
    ratio = noise_rolloff(contexts[DEFAULT_ANTIALIAS_HZ])
    if ratio < ROLLOFF_RATIO:
        return [(DEFAULT_ANTIALIAS_HZ,
                 f"noise rolls off above {DEFAULT_ANTIALIAS_HZ:g} Hz (ratio {ratio:.3f})")]
    reason = (f"white residual noise (ratio {ratio:.2f}): no filter, or one drowned by excess "
              "noise; the simpler diagnosis decides")
    return [(None, reason), (DEFAULT_ANTIALIAS_HZ, reason)]
