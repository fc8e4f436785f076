"""Typed results: the one record between analysis, uncertainty, verdicts, report and records.

Analyses return these models; the engine assembles them into :class:`RunResults` (written as
``results.json``); the uncertainty and verdict stages fill in their fields; reports and the
records store read them and nothing else. ``aatest schema --results`` exports the JSON Schema.

- ``base``      the base model, uncertainty budget rows, the certified-result fields, verdicts
- one module per analysis result (``sync``, ``reference``, ``bias``, ``scale_factor``,
  ``frf``, ``transfer_function``, ``temperature``, ``misalignment``, ``noise``)
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
from aatest.results.root import SCHEMA_VERSION, AnalysisBlock, RunResults

__all__ = [
    "SCHEMA_VERSION",
    "AnalysisBlock",
    "BudgetRow",
    "Certified",
    "DecisionRule",
    "Overall",
    "ResultModel",
    "RunResults",
    "Verdict",
    "VerdictValue",
]
