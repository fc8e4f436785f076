"""``analysis.noise``: output noise at rest per channel (method §1.3); ``analysis.drift``: bias
drift and long-τ Allan deviation of a long static record."""

from __future__ import annotations

from typing import ClassVar

from pydantic import Field

from aatest.results._fields import PerChannel, Real
from aatest.results.base import DATASHEET_FLAGS, Certified, ResultModel


class AllanTerms(ResultModel):
    """Overlapping Allan deviation (°/s²) and the noise terms read off it."""

    tau_s: list[Real]
    adev: list[Real]
    white_noise_per_sqrt_hz: Real | None = None
    bias_instability: Real | None = None
    random_walk: Real | None = None


class NoiseChannel(Certified):
    """Noise figures of one channel over its static steps; the certified value (U, budget)
    is ``rms_max_v``, the largest record's RMS (the judged one)."""

    #: the analysis' own pass/fail flags of schema 1; verdicts are the engine's
    retired_keys: ClassVar[frozenset[str]] = DATASHEET_FLAGS

    rms_v: Real = Field(description="mean DC–band RMS over the static steps, V")
    rms_max_v: Real
    rms_per_step_v: list[Real]
    rms_dps2: Real = Field(description="rms_v divided by the scale factor in use, °/s²")
    scale_v_per_dps2_used: Real | None = Field(
        None, description="calibrated scale factor if available, else the datasheet's")
    band_hz: Real
    psd_floor_v_per_sqrt_hz: Real
    allan_dps2: AllanTerms
    record_step: str
    record_s: Real | None = Field(None, description="length of that record (the PSD and "
                                  "Allan deviation are of it), s")


class NoiseResult(PerChannel[NoiseChannel]):
    """Channel → noise."""


class AllanFit(ResultModel):
    """Noise terms from a least-squares fit of the Allan variance of a long static record,
    σ²(τ) = N²/τ + (0.664·B)² + K²·τ/3 + R²·τ²/2 (IEEE 952/1554-style reading, rate-like
    output in °/s²): N white noise in (°/s²)·√s (angle-random-walk-like), B bias instability in
    °/s², K rate random walk in (°/s²)/√s, R rate ramp (steady drift) in (°/s²)/s."""

    white_noise_dps2_sqrt_s: Real | None = Field(None, description="N, (°/s²)·√s")
    bias_instability_dps2: Real | None = Field(None, description="B, °/s²")
    rate_random_walk_dps2_per_sqrt_s: Real | None = Field(None, description="K, (°/s²)/√s")
    rate_ramp_dps2_per_s: Real | None = Field(None, description="R, (°/s²)/s")


class DriftInterval(ResultModel):
    """Mean output bias and temperature over one reporting interval of the record."""

    start_h: Real = Field(description="interval start after the record's first sample, h")
    bias_v: Real = Field(description="mean output at rest, V")
    temperature_c: Real | None = Field(None, description="mean logged temperature, °C")


class DriftChannel(ResultModel):
    """Bias drift and long-τ Allan deviation of one channel over the longest static record."""

    record_step: str
    duration_s: Real = Field(description="record length, s")
    average_s: Real = Field(description="averaging interval the record was reduced to, s")
    bias_v: Real = Field(description="mean output at rest over the record, V")
    drift_v_per_h: Real = Field(description="slope of the least-squares line of the bias, V/h")
    drift_sigma_v_per_h: Real = Field(description="standard error of that slope, V/h")
    drift_dps2_per_h: Real = Field(description="the slope in input units, (°/s²)/h")
    peak_to_peak_v: Real = Field(description="peak-to-peak of the 60 s means of the bias, V")
    scale_v_per_dps2_used: Real = Field(description="datasheet scale factor, V/(°/s²)")
    allan_dps2: AllanTerms
    allan_fit: AllanFit
    max_tau_s: Real = Field(description="longest averaging time of the Allan deviation, s")
    intervals: list[DriftInterval]


class DriftResult(PerChannel[DriftChannel]):
    """Channel → bias drift and Allan deviation of a long static record."""
