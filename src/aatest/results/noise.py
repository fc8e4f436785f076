"""``analysis.noise``: output noise at rest per channel (method §1.3)."""

from __future__ import annotations

from typing import ClassVar

from pydantic import Field

from aatest.results._fields import PerChannel, Real
from aatest.results.base import DATASHEET_FLAGS, ResultModel


class AllanTerms(ResultModel):
    """Overlapping Allan deviation (°/s²) and the noise terms read off it."""

    tau_s: list[Real]
    adev: list[Real]
    white_noise_per_sqrt_hz: Real | None = None
    bias_instability: Real | None = None
    random_walk: Real | None = None


class NoiseChannel(ResultModel):
    """Noise figures of one channel over its static steps."""

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


class NoiseResult(PerChannel[NoiseChannel]):
    """Channel → noise."""
