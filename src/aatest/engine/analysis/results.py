"""``results.json``: the one document between analysis and report (docs/interfaces.md §1)."""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from aatest.engine.analysis.passes import AnalysisResults
from aatest.engine.dataset import Dataset
from aatest.engine.errors import InputError

RESULTS_FILE = "results.json"


def _jsonable(value: Any) -> Any:
    """numpy scalars/arrays → plain JSON; NaN/inf → None (JSON has no NaN)."""
    if isinstance(value, Mapping):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist())
    if isinstance(value, (np.bool_,)):
        return bool(value)
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        f = float(value)
        return f if math.isfinite(f) else None
    if isinstance(value, complex):
        return [value.real, value.imag]
    return value


def step_summaries(data: Dataset) -> list[dict[str, Any]]:
    """What was recorded per step, for the results and the report."""
    rows = []
    for sd in data.steps:
        row = sd.step.model_dump(mode="json", exclude_none=True)
        row.update(table_samples=len(sd.table), daq_samples=len(sd.daq), status="recorded")
        rows.append(row)
    return rows


def build_results(
    data: Dataset, analysis: AnalysisResults, lab_duration_s: float, wall_duration_s: float
) -> dict[str, Any]:
    meta = dict(data.metadata)
    return _jsonable({
        "procedure": data.procedure,
        "rig": meta.get("rig", {}),
        "steps": step_summaries(data),
        "analysis": analysis.values,
        "analysis_errors": analysis.errors,
        "analysis_skipped": analysis.skipped,
        "lab_duration_s": lab_duration_s,
        "wall_duration_s": wall_duration_s,
        "metadata": {k: v for k, v in meta.items() if k != "plan"},
        "figures": analysis.figures,
    })


def write_results(results: Mapping[str, Any], run_dir: Path) -> Path:
    """Write atomically so a crash never leaves half a results file."""
    path = run_dir / RESULTS_FILE
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(results, indent=2, allow_nan=False), encoding="utf-8")
    os.replace(tmp, path)
    return path


def read_results(run_dir: Path) -> dict[str, Any]:
    path = run_dir / RESULTS_FILE
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError as exc:
        raise InputError(f"{path}: no results; run `aatest analyze {run_dir}` first") from exc
    except json.JSONDecodeError as exc:
        raise InputError(f"{path}:{exc.lineno}:{exc.colno}: invalid JSON: {exc.msg}") from exc
