"""What the station offers: procedures by id, their validation, recent runs and their files.

The browser never sends a file-system path: procedures are named by an id
(``shipped/<file>``, ``lab/<file>`` or ``upload/<file>``) looked up in the listing built here,
runs by their directory name looked up in the runs directory, and run files by a fixed set of
names. The history comes from the runs directory, or from the calibration records store when
the station is started with ``--records`` (:class:`RecordsHistory`).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from aatest.engine.errors import AatestError, InputError, ProblemsError
from aatest.engine.run.progress import describe
from aatest.engine.run.run_state import STATE_FILE, RunState
from aatest.engine.run.runner import procedure_sha256
from aatest.station.verdicts import banner

if TYPE_CHECKING:
    from aatest.records.models import CalibrationRecord
    from aatest.records.store import RecordStore

#: run files the page may link to (report plugins write ``report.html``; ``--pdf`` its PDF)
RUN_FILES = {"report.html": "text/html", "report.pdf": "application/pdf",
             "results.json": "application/json"}
#: id prefix of procedures uploaded from the browser (kept in the station's upload directory)
UPLOAD_PREFIX = "upload/"
#: the page's group of each id prefix
GROUPS = {"shipped": "Shipped with aatest", "lab": "The lab's procedures",
          "upload": "Uploaded at this station"}


@dataclass(frozen=True)
class Procedures:
    """The shipped procedures, those of an optional lab directory and the uploaded ones, by id."""

    lab_dir: Path | None = None
    upload_dir: Path | None = None

    def listing(self) -> dict[str, Path]:
        """Id → file: ``shipped/<name>.yaml``, ``lab/<name>.yaml``, ``upload/<name>.yaml``."""
        shipped = Path(str(resources.files("aatest") / "procedures"))
        found = {f"shipped/{p.name}": p for p in sorted(shipped.glob("*.yaml"))}
        for prefix, directory in (("lab/", self.lab_dir), (UPLOAD_PREFIX, self.upload_dir)):
            if directory is None or not directory.is_dir():
                continue
            found.update({f"{prefix}{p.name}": p for p in sorted(directory.iterdir())
                          if p.suffix.lower() in (".yaml", ".yml") and p.is_file()})
        return found

    def entries(self) -> list[dict[str, Any]]:
        """What the page lists: id, group, title (the procedure's name), description, sensor.

        A file that does not load is still listed, by its file name and first problem, so
        the operator sees why it cannot be started (Validate shows every problem).
        """
        return [_entry(procedure_id, path) for procedure_id, path in self.listing().items()]

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


def _entry(procedure_id: str, path: Path) -> dict[str, Any]:
    """One listed procedure, read (not planned) from its file; cached while it is unchanged."""
    try:
        stat = path.stat()
    except OSError as exc:
        return {"id": procedure_id, "group": "", "title": path.name, "description": str(exc),
                "ok": False}
    return dict(_read_entry(procedure_id, path, stat.st_mtime_ns, stat.st_size))


@functools.lru_cache(maxsize=1024)
def _read_entry(procedure_id: str, path: Path, _mtime_ns: int, _size: int) -> dict[str, Any]:
    from aatest.engine.procedure.loader import parse_procedure
    from aatest.positioned_yaml import read_text

    prefix = procedure_id.split("/", 1)[0]
    entry: dict[str, Any] = {"id": procedure_id, "group": GROUPS.get(prefix, prefix)}
    try:
        procedure = parse_procedure(read_text(path), path.name)
    except ProblemsError as exc:
        return {**entry, "title": path.name, "description": str(exc.problems[0]), "ok": False}
    except (AatestError, OSError) as exc:
        return {**entry, "title": path.name, "description": str(exc), "ok": False}
    return {**entry, "title": procedure.procedure, "description": procedure.description,
            "model": procedure.sensor.model, "serial": procedure.sensor.serial, "ok": True}


def sensor_models() -> list[str]:
    """The sensor models installed (``aatest.sensors`` plugins), for the page's model list."""
    from aatest.engine import registry

    return [ep.name for ep in registry.entry_points("sensor")]


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
    """Recent runs for the history list, and the run directories the page may open."""

    @property
    def runs_dir(self) -> Path:
        """Where the station's runs are written (and their files served from)."""
        ...

    def run_dir(self, name: str) -> Path:
        """The directory of run ``name`` under ``runs_dir``; unknown names are an InputError."""
        ...

    def recent(self, limit: int) -> list[dict[str, Any]]:
        """Newest first: name, procedure, finished, overall verdict, report links."""
        ...

    def source(self) -> dict[str, str]:
        """Where the list comes from, for the page: ``{"source": "runs" | "records", …}``."""
        ...


def _is_run_dir(candidate: Path) -> bool:
    """Whether ``candidate`` is a real run directory: no symbolic link, a readable state file."""
    try:
        return (not candidate.is_symlink() and candidate.is_dir()
                and _plain_file(candidate / STATE_FILE))
    except OSError:  # unreadable (permissions, I/O error): not a run the station can show
        return False


def _run_dir_named(runs_dir: Path, name: str) -> Path:
    """The run directory ``name`` directly under ``runs_dir``; anything else is refused.

    Symbolic links are refused too: a link in the runs directory could lead anywhere.
    """
    candidate = runs_dir / name
    if "/" in name or "\\" in name or "\0" in name or name in ("", ".", "..") or not (
        _is_run_dir(candidate)
    ):
        raise InputError(f"unknown run {name!r}")
    return candidate


@dataclass(frozen=True)
class RunsDirHistory:
    """History read from the run directories under ``runs_dir`` (each has run_state.json)."""

    runs_dir: Path

    def run_dir(self, name: str) -> Path:
        """The directory of run ``name``; names with separators or unknown runs are refused."""
        return _run_dir_named(self.runs_dir, name)

    def recent(self, limit: int) -> list[dict[str, Any]]:
        """The ``limit`` most recently changed runs, newest first.

        A directory that cannot be read or summarised (permissions, a broken state file, a
        symbolic link) is left out of the list rather than failing it for every browser.
        """
        try:
            entries = list(self.runs_dir.iterdir())
        except OSError:
            return []
        dated = []
        for d in entries:
            try:
                if _is_run_dir(d):
                    dated.append(((d / STATE_FILE).stat().st_mtime, d))
            except OSError:
                continue
        dated.sort(key=lambda pair: pair[0], reverse=True)
        rows = []
        for _mtime, d in dated:
            row = _readable_summary(d)
            if row is not None:
                rows.append(row)
            if len(rows) == limit:
                break
        return rows

    def source(self) -> dict[str, str]:
        """The runs directory (its name only: the page needs no local path)."""
        return {"source": "runs", "where": self.runs_dir.name}


@dataclass(frozen=True)
class RecordsHistory:
    """History read from the calibration records store (``aatest station --records URL``).

    Lists the newest registered calibrations of every station and command that used the store,
    not only this station's runs. Run files and Resume stay tied to the runs directory: a record
    whose bundle lies in a run directory under ``runs_dir`` links its files; others (runs made
    elsewhere) are listed without links, so no path stored in the database is served.
    """

    store: RecordStore
    runs_dir: Path

    def run_dir(self, name: str) -> Path:
        """The directory of run ``name`` under ``runs_dir`` (as :class:`RunsDirHistory`)."""
        return _run_dir_named(self.runs_dir, name)

    def recent(self, limit: int) -> list[dict[str, Any]]:
        """The ``limit`` newest current calibrations in the store, newest first."""
        return [self._row(record) for record in self.store.recent(limit)]

    def source(self) -> dict[str, str]:
        """The store's URL without its password."""
        return {"source": "records", "store": self.store.name}

    def _local_run(self, bundle: str) -> Path | None:
        """The run directory under ``runs_dir`` that holds ``bundle``, if any."""
        run_dir = Path(bundle).parent
        try:
            inside = run_dir.resolve().parent == self.runs_dir.resolve()
            return _run_dir_named(self.runs_dir, run_dir.name) if inside else None
        except (InputError, OSError):
            return None

    def _row(self, record: CalibrationRecord) -> dict[str, Any]:
        local = self._local_run(record.bundle)
        return {
            "name": local.name if local is not None else None,
            "procedure": record.procedure, "finished": True,
            "overall": record.overall_verdict,
            "files": present_files(local) if local is not None else [],
            "certificate_number": record.certificate_number,
            "unit": f"{record.model}/{record.serial}", "serial": record.serial,
            "calibrated_utc": record.calibrated_utc.isoformat(timespec="seconds"),
            "operator": record.operator, "command": record.command, "source": "records",
            "kind": record.kind,
        }


def history_for(records: str | None, runs_dir: Path) -> History:
    """The history source: the records store at ``records`` when given, else the runs directory.

    The store is opened (and migrated) once, when the station starts: an unreachable database
    is an error then (exit 2), not a history list that silently stays empty.
    """
    if records is None:
        return RunsDirHistory(runs_dir)
    from aatest.records.store import RecordStore

    return RecordsHistory(RecordStore.open(records), runs_dir)


def _plain_file(path: Path) -> bool:
    """Whether ``path`` is a regular file itself, not a symbolic link to one (never followed)."""
    try:
        return path.is_file() and not path.is_symlink()
    except OSError:
        return False


def present_files(run_dir: Path) -> list[str]:
    """The run files the page may link: only those on disk (no PDF link when none was printed)."""
    return sorted(n for n in RUN_FILES if _plain_file(run_dir / n))


def _readable_summary(run_dir: Path) -> dict[str, Any] | None:
    """:func:`run_summary`, or None when the directory's files cannot be read or parsed."""
    try:
        return run_summary(run_dir)
    except (AatestError, OSError, ValueError, KeyError, TypeError, AttributeError):
        return None


def run_summary(run_dir: Path) -> dict[str, Any]:
    """One history row: state, verdict and which report files exist."""
    state = RunState.load(run_dir)
    summary: dict[str, Any] = {
        "name": run_dir.name, "procedure": state.procedure, "finished": state.finished,
        "prompt_answers": state.prompt_answers, "overall": None,
        "files": present_files(run_dir),
    }
    summary.update(results_summary(run_dir))
    return summary


def results_summary(run_dir: Path) -> dict[str, Any]:
    """The verdict banner and the judged quantities with U, from ``results.json`` if present."""
    from aatest.engine.analysis.results_file import RESULTS_FILE, read_results
    from aatest.engine.errors import InputError

    if not _plain_file(run_dir / RESULTS_FILE):
        return {}
    try:
        results = read_results(run_dir)
    except InputError as exc:  # shown on the page, not hidden: the file is unreadable
        return {"results_error": str(exc)}
    from aatest.engine.simulation import SIMULATION_TITLE, is_simulation

    unit = results.metadata.unit()
    return {**banner(results), "analysis_errors": dict(results.analysis_errors),
            "signed": results.signature is not None,
            # a run on any simulated part says so wherever its result is shown
            "simulation": SIMULATION_TITLE if is_simulation(results) else None,
            "serial": unit.serial, "model": unit.model}
