"""``results.json``: the one document between analysis and report (docs/interfaces.md §1).

The engine builds a typed :class:`~aatest.results.RunResults` and writes its JSON dump
(NaN and infinities become ``null``); :func:`read_results` reads any results.json back into the
same model, including files written before it was typed.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from pydantic import TypeAdapter, ValidationError

from aatest.engine.analysis.passes import AnalysisResults
from aatest.engine.errors import InputError
from aatest.recording.dataset import Dataset
from aatest.recording.temperatures import logged_temperature
from aatest.results import SCHEMA_VERSION, AnalysisBlock, RunResults
from aatest.storage import Where

RESULTS_FILE = "results.json"


def step_summaries(data: Dataset) -> list[dict[str, Any]]:
    """What was recorded per step, for the results and the report."""
    rows = []
    for sd in data.steps:
        row = sd.step.model_dump(mode="json", exclude_none=True)
        row.update(table_samples=sd.samples("table"), daq_samples=sd.samples("daq"),
                   daq_extremes=sd.daq_extremes(), status="recorded")
        rows.append(row)
    return rows


def _scalar(value: Any) -> Any:
    """numpy scalars and arrays as Python values; anything else as its text."""
    return value.tolist() if hasattr(value, "tolist") else str(value)


def plain_metadata(meta: dict[str, Any]) -> dict[str, Any]:
    """The run metadata (without the plan) as plain JSON values."""
    plain: dict[str, Any] = json.loads(json.dumps(
        {k: v for k, v in meta.items() if k != "plan"}, default=_scalar))
    return plain


def build_results(
    data: Dataset, analysis: AnalysisResults, lab_duration_s: float, wall_duration_s: float,
    *, figures: bool = True,
) -> RunResults:
    """Assemble the typed results of one analysis pass.

    ``lab_duration_s`` is the lab time the recorded steps took (s); ``wall_duration_s`` the
    computer time of the run (s). ``figures`` False: without the analyses' figures, for a
    caller that takes them later (they may still be drawn aside).
    """
    meta = {"sensors": [s.model_dump(mode="json") for s in data.sensors], **data.metadata}
    return RunResults(
        schema_version=SCHEMA_VERSION,
        procedure=data.procedure,
        rig=plain_metadata({"rig": meta.get("rig") or {}})["rig"],
        steps=step_summaries(data),
        analysis=AnalysisBlock.model_validate(analysis.values),
        analysis_errors=analysis.errors,
        analysis_skipped=analysis.skipped,
        lab_duration_s=lab_duration_s,
        wall_duration_s=wall_duration_s,
        metadata=plain_metadata(meta),
        figures=analysis.figures if figures else {},
        logged_temperature=logged_temperature(data),
    )


def results_json(results: RunResults | Mapping[str, Any]) -> dict[str, Any]:
    """The JSON document of ``results`` (what is written, and what report plugins read); a
    document that is already plain JSON values is returned as a copy."""
    if isinstance(results, RunResults):
        return results.model_dump(mode="json")
    return dict(results)


def write_results(results: RunResults | Mapping[str, Any], run_dir: Path) -> Path:
    """Write atomically so a crash never leaves half a results file."""
    path = run_dir / RESULTS_FILE
    tmp = path.with_suffix(".json.tmp")
    text = json.dumps(results_json(results), indent=2, allow_nan=False)
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path)
    return path


def _typed_extra(results: RunResults, path: Where) -> RunResults:
    """Results of third-party analyses validated by their installed plugin's ``Result`` type
    (kept as plain JSON values when the plugin is not installed here)."""
    from aatest.engine.analysis import plugins

    installed = set(plugins.installed_names())
    typed: dict[str, Any] = {}
    for key, value in results.analysis.extra.items():
        if key not in installed:
            typed[key] = value
            continue
        plugin = plugins.load(key)
        try:
            typed[key] = TypeAdapter(plugin.cls.Result).validate_python(value)
        except ValidationError as exc:
            raise InputError(f"{path}: analysis.{key}: not a result of {plugin.describe()}: "
                             f"{exc.errors(include_url=False)[0]['msg']}") from exc
    results.analysis.extra = typed
    return results


def read_results(run_dir: Where) -> RunResults:
    """Read ``run_dir/results.json`` into the typed model.

    Raises
    ------
    InputError
        When the file is missing, is not JSON, or does not match the results schema (or a
        third-party result does not match its plugin's ``Result``).
    """
    path = run_dir / RESULTS_FILE
    try:
        return _typed_extra(RunResults.model_validate_json(path.read_bytes()), path)
    except FileNotFoundError as exc:
        raise InputError(f"{path}: no results; run `aatest analyze {run_dir}` first") from exc
    except ValidationError as exc:
        first = exc.errors(include_url=False)[0]
        where = ".".join(str(p) for p in first.get("loc", ()))
        raise InputError(f"{path}: {where}: {first['msg']} ({exc.error_count()} problem(s))"
                         ) from exc
