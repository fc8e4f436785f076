"""The pieces every result model shares: strictness, uncertainty statements and verdicts.

Field names are the keys of ``results.json`` (docs/interfaces.md §1) and are part of the public
interface: add fields, never rename them. Units are in the names (``_v``, ``_dps2``, ``_deg``).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

#: ILAC-G8 decision rules: plain comparison, guard band = U, or shared risk (U reported only)
DecisionRule = Literal["simple", "guarded", "shared-risk"]
#: one verdict; the ``conditional-*`` forms mean the value lies within U of its limit;
#: ``not judged``: the procedure asked for the quantity but it was not measured (see ``reason``)
VerdictValue = Literal["pass", "fail", "conditional-pass", "conditional-fail", "not judged"]
#: the overall verdict of a run: ``none`` when nothing was judged, ``incomplete`` when something
#: asked was not judged and nothing failed (never ``pass``: not measured is never passed)
Overall = Literal["pass", "fail", "conditional-pass", "conditional-fail", "incomplete", "none"]
#: where a limit came from: the procedure's ``acceptance.limits``, the sensor's datasheet, or
#: the logger (no sample at its input range's rails, :mod:`aatest.metrology.logger_rails`)
LimitSource = Literal["procedure", "datasheet", "logger"]


#: the analyses' own pass/fail flags, written before verdicts moved into the engine (schema 1)
DATASHEET_FLAGS = frozenset({
    "bias_within_datasheet", "g_sensitivity_within_datasheet", "scale_within_datasheet",
    "bias_coefficient_within_datasheet", "scale_coefficient_within_datasheet", "within_datasheet",
    "within_limit", "cross_within_limit",
})


class ResultModel(BaseModel):
    """Base of every result model: unknown keys are errors, so a misspelt key cannot hide.

    A key an earlier version wrote and this one retired is named in ``retired_keys``: it is
    read and dropped (never written again), so an old results.json still loads while a
    misspelt key is still an error.
    """

    model_config = ConfigDict(extra="forbid", validate_assignment=True)
    #: keys of older results.json files that are accepted on reading and dropped
    retired_keys: ClassVar[frozenset[str]] = frozenset()

    @model_validator(mode="before")
    @classmethod
    def _drop_retired_keys(cls, data: Any) -> Any:
        """Drop the retired keys of an old document before the strict validation."""
        if cls.retired_keys and isinstance(data, Mapping) and cls.retired_keys & data.keys():
            return {k: v for k, v in data.items() if k not in cls.retired_keys}
        return data


class BudgetRow(ResultModel):
    """One row of a GUM uncertainty budget (JCGM 100), in the final quantity's unit.

    ``basis`` says where the number comes from (measured from the data, the rig's stated
    accuracy, a datasheet, or "not evaluated"), which an assessor needs for every row.
    """

    name: str = Field(description="machine name of the input quantity")
    label: str = Field(description="what the input is, for the certificate")
    value: float = Field(description="estimate of the input, in its own unit")
    standard_uncertainty: float = Field(ge=0, description="u(x_i), in the input's unit")
    unit: str = Field("", description="unit of the input")
    distribution: str = Field("normal", description="normal | rectangular | cosine_error")
    sensitivity: float | None = Field(None, description="c_i = ∂y/∂x_i")
    contribution: float = Field(ge=0, description="|c_i|·u(x_i), in the quantity's unit")
    basis: str = Field("", description="where the number comes from")
    quantity: str = Field("", description="the input quantity, as the certificate names it")
    type: Literal["A", "B"] = Field(
        "B", description="GUM evaluation type: A statistical from this run's data, B otherwise")
    evaluated: bool = Field(
        True, description="False: the component exists but could not be quantified (shown "
        "as 'not evaluated' with the reason in basis; its contribution is 0)")


class Certified(ResultModel):
    """Fields of a certified result: its expanded uncertainty and the budget behind it.

    Filled by the uncertainty stage after the analyses (``None``/empty until then, and for
    results the lab does not certify).
    """

    expanded_uncertainty: float | None = Field(
        None, ge=0, description="U in the value's unit, U = k·u_c")
    coverage_factor: float | None = Field(None, gt=0, description="k")
    coverage_probability: float | None = Field(None, gt=0, lt=1, description="e.g. 0.95")
    budget: list[BudgetRow] = Field(default_factory=list, description="GUM budget rows")
    measurand: str = Field("", description="the precise quantity the value and U are of")


class Verdict(ResultModel):
    """One judged quantity (docs/interfaces.md §1 ``verdicts``), decided by the engine only."""

    quantity: str = Field(description="e.g. scale_factor_deviation_pct, bias_deviation_v; an "
                          "analysis key when a listed analysis did not apply")
    channel: str = Field(description="sensor channel (or sensor name for misalignment)")
    value: float | None = Field(description="the judged value, in the limit's unit; null when "
                                "not judged")
    limit: float | None = Field(ge=0, description="acceptance limit on |value|")
    expanded_uncertainty: float | None = Field(None, ge=0, description="U of value, same unit")
    rule: DecisionRule
    verdict: VerdictValue
    unit: str = Field("", description="unit of value, limit and U")
    limit_source: LimitSource | None = Field(
        None, description="procedure: acceptance.limits; datasheet: the sensor's datasheet; "
        "logger: the sensor logger's input range")
    reason: str = Field("", description="why a quantity was not judged (empty when judged)")
