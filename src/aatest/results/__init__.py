"""Typed results: the one record between analysis, uncertainty, verdicts, report and records.

Analyses return these models; the engine assembles them into :class:`RunResults` (written as
``results.json``); the uncertainty and verdict stages fill in their fields; reports and the
records store read them and nothing else. ``aatest schema --results`` exports the JSON Schema.

- ``base``      the base model, uncertainty budget rows, the certified-result fields, verdicts
- one module per analysis result (sync, reference, bias, scale factor, FRF, …)
- ``root``      :class:`RunResults`, the whole ``results.json``
"""

from aatest.results.base import (
    BudgetRow,
    Certified,
    DecisionRule,
    Overall,
    ResultModel,
    Verdict,
    VerdictValue,
)

__all__ = [
    "BudgetRow",
    "Certified",
    "DecisionRule",
    "Overall",
    "ResultModel",
    "Verdict",
    "VerdictValue",
]
