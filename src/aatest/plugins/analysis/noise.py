"""Output noise of the sensors at rest: PSD, band RMS and Allan deviation (docs/method.md §1.3).

From the static steps: Welch PSD of the output (V²/Hz), RMS in the datasheet band DC–400 Hz
(mean removed) against the datasheet limit, and the overlapping Allan deviation of the output
expressed in °/s² (allantools, frequency data) on the longest record, with the usual noise
terms read off the log-log curve: white noise N (slope −½, σ·√τ), bias instability B
(flat minimum / 0.664) and random walk K (slope +½, σ/√(τ/3)).

The ``drift`` analysis of long static records is :mod:`aatest.plugins.analysis.drift` (its own
entry point); this module uses its Allan-deviation term fit (:func:`allan_terms_of`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np
from pydantic import BaseModel, ConfigDict, Field
from scipy import signal

from aatest.clocksync.freeze_pulse import SyncedStep
from aatest.engine.interfaces import AnalysisContext, AnalysisOutput
from aatest.engine.requirements import Requirement
from aatest.plugins.analysis import needs
from aatest.plugins.analysis._common import options_of, scale_in_use, steps_of
from aatest.plugins.analysis.drift import allan_terms_of
from aatest.plugins.analysis.streaming import StaticReduction, band_rms_of, reduce_static
from aatest.presentation.figures import new_figure, tight_layout, to_svg
from aatest.recording.dataset import Dataset, SensorInfo
from aatest.results.noise import NoiseResult

__all__ = ["BAND_HZ", "NoiseAnalysis", "NoiseOptions", "allan_terms", "band_rms", "sensor_noise"]

BAND_HZ = 400.0


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
    """Noise figures of one sensor over its static steps, and the PSD/Allan figure.

    One pass over each record, block by block (:mod:`.streaming`): its band RMS from the
    Welch PSD and, of the longest, the PSD and the Allan deviation (of means of
    :func:`~aatest.plugins.analysis.streaming.allan_block` samples: the samples themselves up
    to 2^18, so an hours-long record costs what a 2-minute one does).
    """
    rms: list[float] = []
    longest: tuple[SyncedStep, StaticReduction] | None = None
    for s in steps:
        found = reduce_static(s.daq_blocks([sensor.channel]), [sensor.channel],
                              s.sample_rate_hz, len(s), spectra=True, allan=True)
        red = found[sensor.channel]
        assert red.welch is not None  # asked for
        f, psd = red.welch.result()
        rms.append(band_rms_of(f, psd, band_hz))
        if longest is None or len(s) > len(longest[0]):
            longest = (s, red)
    assert longest is not None
    step, red = longest
    assert red.welch is not None and red.allan is not None  # asked for
    f, psd = red.welch.result()
    per = red.allan.per_block
    means = red.allan.means()
    allan = allan_terms((means - red.moments.mean) / scale_v_per_dps2, step.sample_rate_hz / per)
    worst = float(max(rms))
    values = {"rms_v": float(np.mean(rms)), "rms_max_v": worst, "rms_per_step_v": rms,
              "rms_dps2": float(np.mean(rms)) / scale_v_per_dps2, "band_hz": band_hz,
              "scale_v_per_dps2_used": scale_v_per_dps2,
              "psd_floor_v_per_sqrt_hz": float(np.sqrt(np.median(psd[(f > 1) & (f < band_hz)]))),
              "allan_dps2": allan, "record_step": step.step.id,
              "record_s": len(step) / step.sample_rate_hz}
    fig, ax = new_figure(2, height_in=2.4)
    ax[0, 0].loglog(f[1:], np.sqrt(psd[1:]), lw=0.6, rasterized=True)
    ax[0, 0].set(xlabel="frequency / Hz", ylabel="V/√Hz", title=f"noise {sensor.channel}")
    ax[1, 0].loglog(allan["tau_s"], allan["adev"], "o-", ms=3)
    ax[1, 0].set(xlabel="τ / s", ylabel="Allan dev. / (°/s²)")
    tight_layout(fig)
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
    #: what the plan must hold (checked by ``validate``; aatest.engine.requirements)
    requirements: ClassVar[tuple[Requirement, ...]] = needs.STATIC
    #: the acceptance quantities it produces (judged when it is listed)
    judges: ClassVar[tuple[str, ...]] = ("noise_rms_v",)
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
