"""``analysis.scale_factor``: polynomial scale-factor calibration per channel (method §4.3)."""

from __future__ import annotations

from typing import Annotated, Any, ClassVar, Literal

from pydantic import BeforeValidator, Field

from aatest.results._fields import PerChannel, Real
from aatest.results.base import DATASHEET_FLAGS, Certified, ResultModel

#: acceleration references a scale factor can be calibrated against (docs/interfaces.md §2)
ReferenceChoice = Literal["fit", "table_estimate", "central", "five_point", "smoothed",
                          "sliding_mode"]
#: the implementation names used before the public ones (still accepted, read as these)
REFERENCE_ALIASES: dict[str, str] = {"smooth": "smoothed", "table": "table_estimate",
                                     "savgol": "fit", "levant": "sliding_mode",
                                     "central_rate": "central", "five_point_rate": "five_point"}


def _public_reference(value: Any) -> Any:
    return REFERENCE_ALIASES.get(value, value) if isinstance(value, str) else value


#: a reference name; the old implementation names are mapped to the public ones
ReferenceName = Annotated[ReferenceChoice, BeforeValidator(_public_reference)]


class PolyFitSummary(ResultModel):
    """Statistics of a fitted polynomial (ascending powers, physical units)."""

    order: int
    coefficients: list[Real]
    std_uncertainty: list[Real]
    ci95: list[list[Real]]
    covariance: list[list[Real]]
    correlation: list[list[Real]]
    sse: Real
    rmse: Real
    r2: Real
    n: int


class Validation(ResultModel):
    """Cross-validation per order 0..max: mean validation RMSE and identification nAIC."""

    rmse_dps2: list[Real]
    naic: list[Real]


class InverseModel(ResultModel):
    """volts = Σ c_i·α^i, α in °/s²."""

    order: int
    coefficients_v: list[Real]
    ci95: list[list[Real]]
    rmse_v: Real
    note: str = ""


class ScaleFactorChannel(Certified):
    """Scale-factor calibration of one channel (certified: ``scale_v_per_dps2``)."""

    #: the analysis' own pass/fail flags of schema 1; verdicts are the engine's
    retired_keys: ClassVar[frozenset[str]] = DATASHEET_FLAGS

    scale_v_per_dps2: Real = Field(description="1/slope of the best straight line, V/(°/s²)")
    scale_u_v_per_dps2: Real
    scale_ci95: list[Real]
    offset_v: Real
    offset_u_v: Real
    order: int = Field(ge=0, description="chosen polynomial order")
    rmse_dps2: Real
    coefficients: list[Real] = Field(description="°/s² from (V − volts_mean_v), ascending")
    ci95: list[list[Real]]
    fit: PolyFitSummary
    volts_mean_v: Real
    validation: Validation
    nonlinearity_dps2: Real = Field(description="curvature of the chosen polynomial against "
                                    "its own best line, °/s² (0 at order ≤ 1; not the study's L)")
    linearity_l_dps2: Real | None = Field(
        None, description="the study's (non)linearity L (Eq. 3.36): RMS over the record of the "
        "model from the ideal line (the straight line against the table's own estimate), °/s²")
    inverse: InverseModel
    reference: ReferenceName = Field(description="the acceleration reference calibrated against")
    alignment_delay_s: Real
    steps: list[str]
    scale_deviation_pct: Real
    nonlinearity_pct_fr: Real = Field(description="curvature of the chosen polynomial within "
                                      "the record, % FR (0 by construction at order ≤ 1)")
    accel_dps2: Real | None = Field(None, description="the peak acceleration level, °/s²")
    frequency_hz: Real | None = Field(None, description="the frequency of the records, Hz")
    temperature_c: Real | None = Field(None, description="the chamber set-point, °C (None: "
                                       "no chamber)")


class ScaleFactorLevel(ScaleFactorChannel):
    """The calibration at one acceleration level (and set-point), certified like the headline."""


class LevelLinearity(ResultModel):
    """Linearity across the acceleration levels (docs/method.md §4.3, the study's way).

    Each level's response y_i = K_i·a_i (V at its peak acceleration a_i) against the best
    straight line through the origin, y = K̂·a: the largest deviation, in °/s², as % of the
    full range (2 × the ±range). A line through the origin has one parameter, so two levels
    already test it; no polynomial order is chosen.
    """

    accel_dps2: list[Real] = Field(description="the levels, °/s²")
    scale_v_per_dps2: list[Real] = Field(description="K_i of each level, V/(°/s²)")
    scale_v_per_dps2_line: Real = Field(description="K̂ of the line through the origin")
    deviation_dps2: list[Real] = Field(description="(y_i − K̂·a_i)/K̂ per level, °/s²")
    nonlinearity_pct_fr: Real = Field(description="max |deviation| / (2·range) · 100")
    temperature_c: Real | None = None


class ScaleFactorHeadline(ScaleFactorChannel):
    """The channel's scale factor: the largest level at the set-point nearest 25 °C (named by
    ``accel_dps2``, ``frequency_hz``, ``temperature_c``), every level, and the linearity."""

    levels: list[ScaleFactorLevel] = Field(
        default_factory=list, description="every acceleration level (and set-point) analysed")
    linearity: LevelLinearity | None = Field(
        None, description="across the levels at the headline set-point (≥ 2 levels)")


class ScaleFactorResult(PerChannel[ScaleFactorHeadline]):
    """Channel → scale-factor calibration."""
