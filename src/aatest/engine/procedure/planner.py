"""Planner: expand a :class:`~aatest.engine.procedure.models.Procedure` into concrete steps.

Generators become :class:`~aatest.engine.steps.PlannedStep` objects in procedure order. Step
ids are ``sNNN-<what>`` (running number, then kind, axis, frequency, acceleration/amplitude,
mounting, repetition), unique and stable for an unchanged procedure. Sine steps carry the
snapped frequency (f = c·Fs/N, c = round(f·N/Fs), halves up — the generic rule), the whole
cycle count c, A = α/(2πf)² in degrees and α = A·(2πf)² in °/s². A chamber step (soak, no
record) precedes the records at each new set-point; later records carry ``temperature_c``.

The planner remembers, per plan, which YAML entry produced each step (``Expansion.sources``)
and which sweep points it dropped with ``skip_outside_envelope: true``
(``Expansion.skipped``), so :func:`aatest.engine.procedure.envelope.check_envelope` can point at the
file position and ``plan --json`` can list the skipped points.

Example
-------
>>> from aatest.engine.procedure.models import Procedure
>>> proc = Procedure.model_validate({"procedure": "demo", "sensor": {"model": "sr207"},
...     "steps": [{"sine": {"axis": "inner", "frequency_hz": 0.4, "accel_dps2": 400}}]})
>>> step = expand(proc).steps[0]
>>> step.id, round(step.frequency_hz, 9), round(step.amplitude_deg, 6)
('s001-sine-inner-0.3967Hz-400dps2', 0.396728516, 64.374433)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from aatest.engine.errors import PluginError, Problem, ProcedureError
from aatest.engine.interfaces import SensorDatasheet, TableEnvelope
from aatest.engine.procedure import generators
from aatest.engine.procedure.envelope import step_violations
from aatest.engine.procedure.expansion import (
    Expansion,
    SkippedPoint,
    YamlPath,
    remember,
    trace_of,
)
from aatest.engine.procedure.generators import snap_frequency, sweep_points
from aatest.engine.procedure.models import Overrides, Procedure, StepEntry
from aatest.engine.steps import Plan, PlannedStep, SensorRef
from aatest.positioned_yaml import locate

#: upper bound on the steps one procedure may expand to
MAX_STEPS = 20_000

__all__ = ["Expansion", "SkippedPoint", "default_datasheet", "expand", "expand_traced",
           "snap_frequency", "sweep_points", "trace_of"]


@dataclass
class _Draft:
    label: str
    source: YamlPath
    fields: dict[str, Any]


@dataclass
class _Walker:
    """Walks the step entries in order, keeping the state generators share."""

    proc: Procedure
    envelope: TableEnvelope
    datasheet: SensorDatasheet
    drafts: list[_Draft] = field(default_factory=list)
    skipped: list[SkippedPoint] = field(default_factory=list)
    prompt: str | None = None
    temperature_c: float | None = None
    repetition: int = 1
    rep_suffix: str = ""
    #: the last snap that moved a frequency (requested, planned), claimed by the next step
    moved: tuple[float, float] | None = None
    snapped: list[tuple[str, float, float]] = field(default_factory=list)

    # --- helpers ------------------------------------------------------------------------------
    def fail(self, path: YamlPath, message: str) -> ProcedureError:
        filename = self.proc.source_file or f"<{self.proc.procedure}>"
        line, col = locate(self.proc.source_tree, path) if self.proc.source_tree else (1, 1)
        return ProcedureError([Problem(filename, line, col, ".".join(map(str, path)), message)])

    def record(self, ov: Overrides, settle_s: float | None = None) -> dict[str, Any]:
        """Sampling fields of a record, with the entry's overrides applied."""
        sampling = self.proc.sampling
        samples = ov.samples or (max(1, round(ov.duration_s * sampling.rate_hz)) if ov.duration_s
                                 else sampling.samples)
        settle = settle_s if settle_s is not None else ov.settle_s
        return {"samples": samples, "sample_rate_hz": sampling.rate_hz,
                "duration_s": samples / sampling.rate_hz,
                "settle_s": sampling.settle_s if settle is None else settle}

    def snap(self, freq_hz: float, mode: str, rec: dict[str, Any]) -> tuple[float, int | None]:
        if mode == "none":
            return freq_hz, None
        snapped, cycles = snap_frequency(freq_hz, rec["sample_rate_hz"], rec["samples"])
        # moved by more than rounding (a frequency already coherent is not reported)
        self.moved = (freq_hz, snapped) if abs(snapped - freq_hz) > 1e-9 * freq_hz else None
        return snapped, cycles

    def emit(self, label: str, source: YamlPath, prompt: str | None = None, **fields: Any) -> None:
        if len(self.drafts) >= MAX_STEPS:
            raise self.fail(source, f"the procedure expands to more than {MAX_STEPS} steps")
        fields.setdefault("repetition", self.repetition)
        if self.temperature_c is not None:
            fields.setdefault("temperature_c", self.temperature_c)
        text = "\n".join(p for p in (self.prompt, prompt) if p)
        if text:
            fields["prompt"] = text
        self.prompt = None
        self.drafts.append(_Draft(label + self.rep_suffix, source, fields))
        if self.moved is not None:  # the step's id is its draft's number and label (_plan)
            number = len(self.drafts)
            self.snapped.append((f"s{number:03d}-{label}{self.rep_suffix}", *self.moved))
            self.moved = None

    def emit_or_skip(self, label: str, source: YamlPath, skip: bool, **fields: Any) -> bool:
        """Emit a sweep point, or drop it when allowed and it leaves the envelope.

        Returns whether the point was emitted.
        """
        if skip:
            candidate = PlannedStep(id=label, **fields)
            broken = [v for v in step_violations(candidate, self.envelope, self.datasheet)
                      if v.skippable]
            if broken:
                self.skipped.append(SkippedPoint(
                    label, source, fields["frequency_hz"], fields["amplitude_deg"],
                    fields["accel_dps2"], fields["group"], tuple(v.message for v in broken),
                    tuple(v.limit for v in broken)))
                return False
        self.emit(label, source, **fields)
        return True

    # --- the walk -----------------------------------------------------------------------------
    def walk(self, entries: tuple[StepEntry, ...], base: YamlPath) -> None:
        for index, entry in enumerate(entries):
            path = (*base, index, entry.kind)
            try:
                getattr(generators, entry.kind)(self, entry.body, path)
            except ProcedureError:
                raise
            except ValueError as exc:
                raise self.fail(path, str(exc)) from exc
            except ArithmeticError as exc:  # e.g. a frequency so high that ω² overflows
                raise self.fail(path, f"cannot expand: {exc}") from exc


def default_datasheet(model: str) -> SensorDatasheet:
    """The datasheet of the installed sensor plugin ``model``, else generic SR207-like values."""
    from aatest.engine import registry  # only needed when the caller gave no datasheet

    try:
        return registry.load("sensor", model).target().datasheet()  # type: ignore[no-any-return]
    except (PluginError, TypeError):
        return SensorDatasheet(model=model)


def _plan(proc: Procedure, drafts: list[_Draft]) -> tuple[Plan, dict[str, YamlPath]]:
    steps, sources = [], {}
    for number, draft in enumerate(drafts, start=1):
        step_id = f"s{number:03d}-{draft.label}"
        steps.append(PlannedStep(id=step_id, **draft.fields))
        sources[step_id] = draft.source
    plan = Plan(procedure=proc.procedure, standard=proc.standard,
                sensor=SensorRef(model=proc.sensor.model, serial=proc.sensor.serial),
                steps=tuple(steps), analysis=proc.analysis,
                report_template=proc.report.template, sign=proc.report.sign)
    return plan, sources


def expand_traced(procedure: Procedure, *, envelope: TableEnvelope | None = None,
                  datasheet: SensorDatasheet | None = None) -> Expansion:
    """Expand ``procedure`` and return the plan with its step sources and skipped points.

    ``envelope``/``datasheet`` decide which points a ``skip_outside_envelope`` sweep drops;
    they default to :class:`TableEnvelope` defaults and :func:`default_datasheet` of the
    procedure's sensor model. Pass the rig's envelope and the sensor plugin's datasheet — the
    ones given to :func:`~aatest.engine.procedure.envelope.check_envelope` — for consistent results.

    Raises
    ------
    ProcedureError
        A generator cannot be expanded (e.g. too many points), located in the source file.
    """
    walker = _Walker(procedure, envelope or TableEnvelope(),
                     datasheet or default_datasheet(procedure.sensor.model))
    walker.walk(procedure.steps, ("steps",))
    if not walker.drafts:
        raise walker.fail(("steps",), "the procedure plans no steps (every point was skipped)")
    plan, sources = _plan(procedure, walker.drafts)
    expansion = Expansion(plan, sources, tuple(walker.skipped), tuple(walker.snapped))
    remember(expansion)
    return expansion


def expand(procedure: Procedure, *, envelope: TableEnvelope | None = None,
           datasheet: SensorDatasheet | None = None) -> Plan:
    """The :class:`Plan` of ``procedure`` (see :func:`expand_traced` for the arguments)."""
    return expand_traced(procedure, envelope=envelope, datasheet=datasheet).plan
