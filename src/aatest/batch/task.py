"""One batch task: re-analyse (or diagnose) one recording, on whichever worker runs it.

A task reads its recording, applies the reference correction (if any), runs the same
analyses, uncertainty budgets and verdicts as ``aatest analyze`` — or the pipeline of
``aatest diagnose`` — and returns plain JSON. It writes nothing: the original bundle and its
certificate stay untouched, and the coordinator stores the result (so a worker killed
mid-task loses only the task it was running, which Dask runs again elsewhere).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from aatest.batch.correction import ReferenceCorrection, corrected
from aatest.batch.method import Mode
from aatest.recording.dataset import Dataset


@dataclass(frozen=True)
class Task:
    """What a worker needs: the recording (a path or URL string) and how to analyse it."""

    subject: str
    record_id: int | None
    recording: str
    mode: Mode
    correction: dict[str, Any] | None = None


def open_dataset(task: Task) -> Dataset:
    """The task's recording as a dataset, as a correct reference would have recorded it."""
    from aatest.recording import read_dataset

    fix = None if task.correction is None else ReferenceCorrection.model_validate(
        task.correction)
    return corrected(read_dataset(task.recording), fix)


def analyse(data: Dataset) -> dict[str, Any]:
    """``aatest analyze`` without writing: results, key quantities and verdicts as JSON."""
    from aatest.engine.analysis.passes import run_analyses
    from aatest.engine.analysis.results_file import build_results, results_json
    from aatest.engine.run.session import decide
    from aatest.engine.simulation import KIND_KEY, kind_of, metadata_of
    from aatest.records import extract

    analysis = run_analyses(data, list(data.metadata.get("analysis", [])))
    lab_s = sum(step.lab_duration_s for step in data.planned)
    results = build_results(data, analysis, lab_s, 0.0)
    setattr(results.metadata, KIND_KEY, kind_of(metadata_of(results)))
    results = decide(results, data)
    stored = results_json(results)
    stored.pop("figures", None)
    return {
        "overall_verdict": str(results.overall),
        "verdicts": extract.verdict_rows(results),
        "quantities": {q.name: {"value": q.value, "expanded_uncertainty": q.expanded_uncertainty,
                                "unit": q.unit} for q in extract.key_quantities(results)},
        "outcome": {"analysis_errors": dict(results.analysis_errors), "results": stored},
    }


def diagnose(data: Dataset) -> dict[str, Any]:
    """``aatest diagnose`` without writing: findings and what stays unexplained, as JSON."""
    from aatest.diagnose.command import _clean
    from aatest.diagnose.pipeline import diagnose_dataset

    doc = _clean(diagnose_dataset(data))
    found = list(doc["findings"]) + list(doc["unexplained"])
    return {
        "overall_verdict": "finding" if found else "explained",
        "verdicts": [],
        "quantities": {},
        "outcome": {key: doc.get(key) for key in (
            "findings", "unexplained", "verdict", "gain", "baseline", "noise_floor")},
    }


def run_task(task: Task) -> dict[str, Any]:
    """The worker's entry point (a top-level function: Dask pickles it by reference)."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(1):  # one task per core: BLAS threads would fight each other
        data = open_dataset(task)
        return analyse(data) if task.mode == "analyze" else diagnose(data)
