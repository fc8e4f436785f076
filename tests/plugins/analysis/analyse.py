"""Run one analysis the way the engine does (with what it requires) and read its result."""

from __future__ import annotations

from typing import Any

from aatest.engine.analysis.passes import run_analysis
from aatest.recording.dataset import Dataset


def analyse(name: str, data: Dataset, **options: Any) -> Any:
    """The result of analysis ``name`` on ``data`` as plain values (the results.json shape)."""
    return run_analysis(name, data, options).result.model_dump()
