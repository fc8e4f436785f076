"""``analysis.cross_axis``: cross-axis sensitivity of a single-axis sensor (issue 32)."""

from __future__ import annotations

from pydantic import Field

from aatest.results._fields import PerChannel, Real
from aatest.results.base import ResultModel


class CrossAxisChannel(ResultModel):
    """Cross-axis sensitivity of one sensor on the inner axis, from outer-axis excitation.

    With the inner axis at θ the outer axis lies at θ in the sensor's transverse plane, so the
    output per transverse acceleration, over the scale factor, is r(θ) = c_x·cos θ + c_y·sin θ;
    two or more positions (not parallel) give (c_x, c_y) and the ratio |c| = √(c_x² + c_y²),
    the worst transverse direction's. It holds the sensor's own cross-axis sensitivity and
    every tilt of its input axis (internal misalignment, seat): this test cannot part them.
    """

    cross_axis_ratio: Real = Field(description="|c|: worst transverse output over in-axis, 1")
    ratio_x: Real = Field(description="c_x: along the outer axis with the inner axis at 0°, 1")
    ratio_y: Real = Field(description="c_y: along the outer axis with the inner axis at 90°, 1")
    expanded_uncertainty: Real | None = Field(None, description="U of cross_axis_ratio (k = 2)")
    coverage_factor: Real = 2.0
    positions_deg: list[Real] = Field(description="inner-axis position θ of each step, °")
    ratios: list[Real] = Field(description="r(θ) of each step, 1")
    standard_uncertainties: list[Real] = Field(description="u(r(θ)) of each step, Type A, 1")
    steps: list[str] = Field(description="the outer-axis sine steps used")
    scale_v_per_dps2_used: Real = Field(
        description="the scale factor dividing the transverse response (calibrated, else the "
        "datasheet's), V/(°/s²)")


class CrossAxisResult(PerChannel[CrossAxisChannel]):
    """Channel → cross-axis sensitivity."""
