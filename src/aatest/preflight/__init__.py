"""Preflight: everything that would fail after the recording fails before anything moves.

``aatest validate`` and the first phase of ``aatest run`` run the same checks, in this order:
the procedure (schema, analysis names and options), every plugin name, the report template
(it loads in the sandbox), the plan (envelope, each analysis' requirements), whether the listed
analyses can use every planned step, whether the DAQ records every channel of the sensor
(:mod:`.sensor_channels`), whether the sensor's nominal output stays inside the stated logger's
input range (:mod:`.logger_range`), the free disk space for the planned recording, the run
directory (new, empty or a run's own), the lab profile, the signing key and its passphrase, and
the records store (reachable, at the schema head). Every failed check is a located problem
(``FILE:LINE:COLUMN``, or the error naming the file or directory) and exit 2; ``validate
--json`` lists each check with its status and message. A check that depends on a failed one is
``skipped`` (say which). Nothing here starts a rig plugin.

Example
-------
>>> from pathlib import Path
>>> import aatest
>>> from aatest.preflight import Site, preflight
>>> shipped = Path(aatest.__file__).parent / "procedures" / "scale-factor.yaml"
>>> report = preflight(shipped, None, Site(records="sqlite:///:memory:"))
>>> report.ok, [c.name for c in report.checks][:3]
(True, ['procedure', 'plugins', 'report template'])
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from aatest.engine import plan_checks, registry
from aatest.engine.errors import AatestError, InputError, Problem, ProblemsError
from aatest.preflight import site_checks
from aatest.preflight.logger_range import logger_range_problems
from aatest.preflight.sensor_channels import sensor_channel_problems

Status = Literal["ok", "failed", "skipped"]
#: the checks that read the plan, in order (skipped when it cannot be made)
_PLAN_CHECKS = ("analysable steps", "sensor channels", "logger range", "disk space")


@dataclass(frozen=True)
class Check:
    """One preflight check: its name, outcome, a message, and the located problems."""

    name: str
    status: Status
    message: str
    problems: tuple[Problem, ...] = ()
    #: a failure that has no place in a file (e.g. a plugin refusing its rig), raised as it is
    error: AatestError | None = None

    def to_json(self) -> dict[str, Any]:
        """The ``validate --json`` entry of this check."""
        return {"name": self.name, "status": self.status, "message": self.message,
                "problems": [{"file": p.file, "line": p.line, "column": p.column,
                              "field": p.field, "message": p.message, "text": str(p)}
                             for p in self.problems],
                **({"error": str(self.error)} if self.error is not None else {})}


class PreflightError(InputError):
    """Every failed preflight check at once: located problems, then unlocated errors (exit 2,
    or the code of the one unlocated error when that is all there is, e.g. a rig fault)."""

    def __init__(self, problems: list[Problem], errors: list[AatestError]) -> None:
        self.problems = problems
        self.errors = errors
        if not problems and len(errors) == 1:
            self.exit_code = errors[0].exit_code
        super().__init__("\n".join([*(str(p) for p in problems),
                                    *(f"error: {e}" if problems or len(errors) > 1 else str(e)
                                      for e in errors)]))


@dataclass(frozen=True)
class Site:
    """What a run uses beside the procedure and the rig file.

    ``migrate``: bring the records store to the schema head now (``run``); ``validate``
    changes nothing. ``out_dir``: where the recording goes (free space is measured there).
    """

    lab: Path | None = None
    key: Path | None = None
    records: str | None = None
    out_dir: Path | None = None
    migrate: bool = False
    unit: Any = None


@dataclass
class Preflight:
    """Every check's outcome and, when the plan could be made, the prepared procedure."""

    checks: list[Check] = field(default_factory=list)
    prepared: Any = None

    @property
    def ok(self) -> bool:
        """No check failed."""
        return all(c.status != "failed" for c in self.checks)

    def problems(self) -> list[Problem]:
        """Every located problem of every failed check, in check order."""
        return [p for c in self.checks for p in c.problems]

    def raise_if_failed(self) -> None:
        """Raise every problem at once (:class:`PreflightError`, exit 2) when a check failed."""
        if not self.ok:
            raise PreflightError(self.problems(),
                                 [c.error for c in self.checks if c.error is not None])

    def to_json(self) -> dict[str, Any]:
        """``aatest validate --json``."""
        return {"ok": self.ok, "checks": [c.to_json() for c in self.checks]}

    def add(self, name: str, problems: list[Problem], message: str,
            error: AatestError | None = None) -> bool:
        """Record one check (failed when it has problems or an error); True when it passed."""
        failed = bool(problems) or error is not None
        self.checks.append(Check(name, "failed" if failed else "ok", message, tuple(problems),
                                 error))
        return not failed

    def skip(self, name: str, because: str) -> None:
        """Record a check that could not run because ``because`` failed."""
        self.checks.append(Check(name, "skipped", f"not checked: the {because} check failed"))


def _guard(run: Callable[[], tuple[list[Problem], str]]
           ) -> tuple[list[Problem], str, AatestError | None]:
    """Run one check; an aatest error it raises is that check's failure, not the end."""
    try:
        problems, message = run()
    except ProblemsError as exc:
        return list(exc.problems), "failed", None
    except AatestError as exc:
        return [], f"failed: {exc}", exc
    return problems, message, None


def _procedure(report: Preflight, path: Path) -> Any:
    from aatest.engine.procedure.loader import parse_procedure
    from aatest.positioned_yaml import read_text

    parsed: list[Any] = []

    def run() -> tuple[list[Problem], str]:
        parsed.append(parse_procedure(read_text(path), str(path)))
        proc = parsed[0]
        return [], f"{proc.procedure}: schema, {len(proc.analysis)} analyses and their options"

    report.add("procedure", *_guard(run))
    return parsed[0] if parsed else None


def _rig_and_plugins(report: Preflight, proc: Any, rig: Path | None) -> bool:
    from aatest.engine.procedure.loader import load_rig, rig_from_procedure

    def run() -> tuple[list[Problem], str]:
        config = load_rig(rig) if rig is not None else rig_from_procedure(proc)
        names = ", ".join(f"{k} {getattr(config, k).plugin}" for k in plan_checks.RIG_KINDS)
        problems = plan_checks.plugin_problems(proc, rig, config)
        return problems, f"sensor {proc.sensor.model}, {names}"

    return report.add("plugins", *_guard(run))


def _template(proc: Any) -> tuple[list[Problem], str]:
    problems = plan_checks.template_problems(proc)
    name = proc.report.template
    return problems, f"{name}: does not load" if problems else f"{name}: loads in the sandbox"


def _plan(report: Preflight, path: Path, rig: Path | None, site: Site) -> None:
    from aatest.engine.run.session import prepare

    def run() -> tuple[list[Problem], str]:
        report.prepared = prepare(path, rig, site.unit)
        plan = report.prepared.plan
        recorded = sum(1 for s in plan.steps if s.recorded)
        return [], (f"{recorded} recorded step{'s' * (recorded != 1)}, lab duration "
                    f"{plan.lab_duration_s:.1f} s")

    if not report.add("plan", *_guard(run)):
        for name in _PLAN_CHECKS:
            report.skip(name, "plan")
        return
    prepared = report.prepared
    problems = plan_checks.analysable_problems(prepared) + plan_checks.soak_problems(prepared)
    report.add("analysable steps", problems,
               "every listed analysis can use the planned steps, the chamber can soak as asked"
               if not problems else "a planned step cannot be analysed or soaked as asked")
    report.add("sensor channels", *_guard(lambda: sensor_channel_problems(prepared)))
    report.add("logger range", *_guard(lambda: logger_range_problems(prepared)))
    report.add("disk space", *plan_checks.disk_problems(prepared, site.out_dir or Path("runs")))


@registry.pinned()  # every check resolves plugins and aliases: read the installation once
def preflight(procedure: Path, rig: Path | None, site: Site | None = None) -> Preflight:
    """Run every preflight check; never raises for a failed check (see :meth:`raise_if_failed`)."""
    site = site or Site()
    report = Preflight()
    proc = _procedure(report, procedure)
    if proc is None:
        for name in ("plugins", "report template", "plan", *_PLAN_CHECKS):
            report.skip(name, "procedure")
    else:
        plugins_ok = _rig_and_plugins(report, proc, rig)
        report.add("report template", *_guard(lambda: _template(proc)))
        if plugins_ok:
            _plan(report, procedure, rig, site)
        else:
            for name in ("plan", *_PLAN_CHECKS):
                report.skip(name, "plugins")
    report.add("run directory", *_guard(lambda: site_checks.run_directory_check(site.out_dir)))
    report.add("lab profile", *_guard(lambda: site_checks.lab_check(site.lab)))
    report.add("signing key", *_guard(lambda: site_checks.key_check(site.key, proc)))
    report.add("records store", *_guard(
        lambda: site_checks.records_check(site.records, site.migrate)))
    return report
