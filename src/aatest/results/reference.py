"""``analysis.reference``: the acceleration references compared on sine steps (method §4.3)."""

from __future__ import annotations

from pydantic import Field, RootModel

from aatest.results._fields import Real
from aatest.results.base import ResultModel


class ReferenceRow(ResultModel):
    """One reference against the smoothed one on one step."""

    rms_diff_dps2: Real = Field(description="RMS difference to the smoothed reference, °/s²")
    runtime_s: Real = Field(description="computation time, s")
    gain: Real | None = Field(None, description="fundamental amplitude ratio (sine steps)")
    phase_deg: Real | None = Field(None, description="fundamental phase difference, °")


class ReferenceResult(RootModel[dict[str, dict[str, ReferenceRow]]]):
    """Step id → reference method → comparison."""
