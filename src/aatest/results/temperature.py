"""``analysis.temperature``: bias and scale factor against temperature (method §4.2)."""

from __future__ import annotations

from typing import ClassVar

from pydantic import Field

from aatest.results._fields import PerChannel, Real
from aatest.results.base import DATASHEET_FLAGS, BudgetRow, Certified


class TemperatureChannel(Certified):
    """Temperature coefficients of one channel (certified: the coefficients).

    The static part (bias) needs ≥ 3 temperatures spanning ≥ 5 °C, the dynamic part (scale
    factor) the same on sine steps; what is missing stays None.
    """

    #: the analysis' own pass/fail flags of schema 1; verdicts are the engine's
    retired_keys: ClassVar[frozenset[str]] = DATASHEET_FLAGS

    bias_coefficient_v_per_c: Real | None = None
    scale_coefficient_per_c: Real | None = None
    hysteresis_v: Real | None = None
    bias_coefficient_u_v_per_c: Real | None = None
    bias_coefficient_ci95_v_per_c: list[Real] | None = None
    bias_at_25c_v: Real | None = None
    temperatures_c: list[Real] | None = None
    bias_v: list[Real] | None = None
    noise_rms_v: list[Real] | None = None
    branch: list[str] | None = Field(None, description="heating | cooling per static step")
    scale_coefficient_u_per_c: Real | None = None
    scale_coefficient_ci95_per_c: list[Real] | None = None
    scale_at_25c_v_per_dps2: Real | None = None
    scale_temperatures_c: list[Real] | None = None
    scale_v_per_dps2: list[Real] | None = None
    scale_hysteresis_per_c_ref: Real | None = None
    scale_coefficient_expanded_uncertainty_per_c: Real | None = Field(
        None, ge=0, description="U of the scale coefficient, 1/°C")
    scale_coefficient_budget: list[BudgetRow] = Field(default_factory=list)
    scale_coefficient_measurand: str = Field("", description="the precise scale-TC quantity")


class TemperatureResult(PerChannel[TemperatureChannel]):
    """Channel → temperature coefficients."""
