"""``analysis.bias``: bias K0 and g-sensitivity per channel from static positions (method §4.1)."""

from __future__ import annotations

from typing import ClassVar

from pydantic import Field

from aatest.results._fields import PerChannel, Real
from aatest.results.base import DATASHEET_FLAGS, BudgetRow, Certified, ResultModel


class LineFit(ResultModel):
    """V = b + k·g over every position of one mounting."""

    bias_v: Real
    g_slope_v_per_g: Real
    residual_rms_v: Real


class MountingBias(ResultModel):
    """Bias of one mounting (original or pivoted); pair statistics need up and down positions."""

    bias_v: Real | None = None
    bias_u_v: Real | None = None
    bias_spread_v: Real | None = None
    bias_ci95_halfwidth_v: Real | None = None
    g_sensitivity_dps2_per_g: Real | None = None
    g_sensitivity_u_dps2_per_g: Real | None = None
    repetitions: int | None = None
    per_repetition_bias_v: list[Real] = Field(default_factory=list)
    line: LineFit


class BiasChannel(Certified):
    """Bias of one sensor channel, overall and per mounting (certified: ``bias_v``)."""

    #: the analysis' own pass/fail flags of schema 1; verdicts are the engine's
    retired_keys: ClassVar[frozenset[str]] = DATASHEET_FLAGS

    bias_v: Real | None = Field(None, description="K0, V (None without up/down pairs)")
    g_sensitivity_dps2_per_g: Real | None = Field(None, description="°/s² per g")
    bias_u_v: Real | None = Field(None, description="standard uncertainty of K0 (type A), V")
    scale_v_per_dps2_used: Real | None = Field(None, description="scale used for g-sensitivity")
    g_sensitivity_limit_dps2_per_g: Real | None = None
    mountings: dict[str, MountingBias] = Field(default_factory=dict)
    g_sensitivity_expanded_uncertainty_dps2_per_g: Real | None = Field(
        None, ge=0, description="U of the g-sensitivity, (°/s²)/g")
    g_sensitivity_budget: list[BudgetRow] = Field(default_factory=list)
    g_sensitivity_measurand: str = Field("", description="the precise g-sensitivity quantity")


class BiasSetpoint(BiasChannel):
    """The bias at one chamber set-point (its ±1 g pair), certified like the headline."""

    temperature_c: Real = Field(description="the chamber set-point, °C")


class BiasHeadline(BiasChannel):
    """The channel's bias; with several set-points, the one nearest 25 °C (``temperature_c``)
    and every set-point's bias in ``setpoints``."""

    temperature_c: Real | None = Field(None, description="set-point of the headline, °C")
    setpoints: list[BiasSetpoint] = Field(default_factory=list,
                                          description="the bias at every chamber set-point")


class BiasResult(PerChannel[BiasHeadline]):
    """Channel → bias."""
