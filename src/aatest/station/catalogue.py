"""What the station offers: procedures by id, their validation, recent runs and their files.

The browser never sends a file-system path: procedures are named by an id
(``shipped/<file>`` or ``lab/<file>``) looked up in the listing built here, runs by their
directory name looked up in the runs directory, and run files by a fixed set of names.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any, Protocol

from aatest.engine.errors import AatestError, InputError, ProblemsError
from aatest.engine.run.progress import describe
from aatest.engine.run.run_state import STATE_FILE, RunState
from aatest.engine.run.runner import procedure_sha256
from aatest.station.verdicts import banner

#: run files the page may link to (report plugins write ``report.html``; ``--pdf`` its PDF)
RUN_FILES = {"report.html": "text/html", "report.pdf": "application/pdf",
             "results.json": "application/json"}


@dataclass(frozen=True)
class Procedures:
    """The shipped procedures and those of an optional lab directory, by id."""

    lab_dir: Path | None = None

    def listing(self) -> dict[str, Path]:
        """Id → file: ``shipped/<name>.yaml`` then ``lab/<name>.yaml``, sorted by name."""
        shipped = Path(str(resources.files("aatest") / "procedures"))
        found = {f"shipped/{p.name}": p for p in sorted(shipped.glob("*.yaml"))}
        if self.lab_dir is not None:
            for pattern in ("*.yaml", "*.yml"):
                found.update({f"lab/{p.name}": p for p in sorted(self.lab_dir.glob(pattern))})
        return found

    def path(self, procedure_id: str) -> Path:
        """The file of a listed id; an unknown id is an InputError (never a path from outside)."""
        listing = self.listing()
        if procedure_id not in listing:
            raise InputError(f"unknown procedure {procedure_id!r}; choose one of the list")
        return listing[procedure_id]

    def by_sha256(self, sha256: str) -> str | None:
        """The id of the listed procedure whose text has this hash (to resume a run)."""
        for procedure_id, path in self.listing().items():
            if procedure_sha256(path.read_text(encoding="utf-8")) == sha256:
                return procedure_id
        return None


def validation(path: Path, rig_file: Path | None) -> dict[str, Any]:
    """Validate like ``aatest validate``: the located problems, or the planned steps."""
    from aatest.engine.run.session import prepare

    try:
        prepared = prepare(path, rig_file)
    except ProblemsError as exc:
        return {"ok": False, "problems": [str(p) for p in exc.problems]}
    except AatestError as exc:
        return {"ok": False, "problems": [str(exc)]}
    plan = prepared.plan
    steps = [{"id": s.id, "kind": s.kind, "motion": describe(s), "prompt": s.prompt,
              "lab_duration_s": s.lab_duration_s} for s in plan.steps]
    return {"ok": True, "procedure": plan.procedure, "steps": steps,
            "lab_duration_s": plan.lab_duration_s}


class History(Protocol):
    """Recent runs for the history list (the runs directory, or a records store later)."""

    def recent(self, limit: int) -> list[dict[str, Any]]:
        """Newest first: name, procedure, finished, overall verdict, report links."""
        ...


@dataclass(frozen=True)
class RunsDirHistory:
    """History read from the run directories under ``runs_dir`` (each has run_state.json)."""

    runs_dir: Path

    def run_dir(self, name: str) -> Path:
        """The directory of run ``name``; names with separators or unknown runs are refused."""
        candidate = self.runs_dir / name
        if "/" in name or "\\" in name or name in ("", ".", "..") or not (
            candidate / STATE_FILE
        ).is_file():
            raise InputError(f"unknown run {name!r}")
        return candidate

    def recent(self, limit: int) -> list[dict[str, Any]]:
        """The ``limit`` most recently changed runs, newest first."""
        if not self.runs_dir.is_dir():
            return []
        dirs = [d for d in self.runs_dir.iterdir() if (d / STATE_FILE).is_file()]
        dirs.sort(key=lambda d: (d / STATE_FILE).stat().st_mtime, reverse=True)
        return [run_summary(d) for d in dirs[:limit]]


def history_for(records: str | None, runs_dir: Path) -> RunsDirHistory:
    """The history source: the runs directory; ``--records`` plugs a records store in here."""
    if records is not None:
        raise InputError(
            f"--records {records}: no records store client is installed in this aatest; "
            "start the station without --records to list runs from --runs"
        )
    return RunsDirHistory(runs_dir)


def run_summary(run_dir: Path) -> dict[str, Any]:
    """One history row: state, verdict and which report files exist."""
    state = RunState.load(run_dir)
    summary: dict[str, Any] = {
        "name": run_dir.name, "procedure": state.procedure, "finished": state.finished,
        "prompt_answers": state.prompt_answers, "overall": None,
        "files": sorted(n for n in RUN_FILES if (run_dir / n).is_file()),
    }
    summary.update(results_summary(run_dir))
    return summary


def results_summary(run_dir: Path) -> dict[str, Any]:
    """The verdict banner and the judged quantities with U, from ``results.json`` if present."""
    path = run_dir / "results.json"
    if not path.is_file():
        return {}
    doc = json.loads(path.read_text(encoding="utf-8"))
    return {**banner(doc), "analysis_errors": doc.get("analysis_errors", {}),
            "signed": doc.get("signature") is not None}
