"""Envelope check: every planned step against the table, the logger and the sensor, before
anything moves (docs/method.md §1.2, §4.4).

Checked per step (peak values of θ = A·sin(ωt): rate A·ω, acceleration A·ω²):

* table: the axes a step moves or positions must be present (``TableEnvelope.axes``; a
  single-axis table has no outer axis, and the limits of an absent axis are not read);
  per-axis peak rate and acceleration vs ``TableEnvelope.inner``/``outer``; constant
  and coordinated rates vs the rate limits; travel for axes that are not continuous;
* terminal frequency: f ≤ ``max_frequency_hz`` (payload-limited, 10 Hz) and, through the
  acceleration limit, f < sqrt(α_max/A)/(2π) (the message states this bound);
* sensor: the acceleration it is asked to see must not exceed the test ceiling
  (``test_ceiling_fraction`` × ``range_dps2``) nor fall below the noise floor ``floor_dps2``
  (the commanded peak acceleration is taken as seen by the sensor: conservative for a unit
  whose sensors lie along every table axis);
* chamber: a set-point within the sensor's ``operating_temperature_c`` (docs/method.md §1.3:
  −40 to 85 °C), not skippable;
* logger: ``sample_rate_hz`` ≤ ``max_log_rate_hz``, ``samples`` ≤ ``log_capacity_samples``,
  except a static step on a rig whose DAQ streams (``TableEnvelope.streaming_daq``): the DAQ
  then records it in chunks and the table logs its full-rate head (:func:`head_step`), so
  it may last hours; dynamic steps keep the capacity rule.

Violations of the motion and sensor limits are *skippable*: a ``sine_sweep`` with
``skip_outside_envelope: true`` drops such points at planning time (they are listed as
skipped; a group with every point outside is an error); everything that reaches
:func:`check_envelope` must pass, or the whole plan is rejected. Problems are located at the YAML
element that produced the steps (for a sweep, its ``amplitudes_deg``/``accelerations_dps2``
element): one problem per violation when the element made one step, else one grouped problem
per element naming how many steps break which limit and the worst case.

Example
-------
>>> from aatest.engine.interfaces import SensorDatasheet, TableEnvelope
>>> from aatest.engine.steps import PlannedStep
>>> step = PlannedStep(id="s001-sine", kind="sine", axis="inner", frequency_hz=1.0,
...                    amplitude_deg=50.0, accel_dps2=1973.9, samples=131072)
>>> [v.limit for v in step_violations(step, TableEnvelope(), SensorDatasheet(model="sr207"))]
['inner.accel_dps2', 'sensor.test_ceiling_dps2']
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from aatest.engine.datasheet import SensorDatasheet
from aatest.engine.errors import EnvelopeError, Problem, ProcedureError
from aatest.engine.interfaces import AxisLimits, TableEnvelope
from aatest.engine.procedure.expansion import YamlPath, trace_of
from aatest.engine.steps import Plan, PlannedStep
from aatest.positioned_yaml import locate as locate_in_tree
from aatest.positioned_yaml import parse_yaml, read_text

#: relative slack so a value exactly at a limit passes despite rounding
_RTOL = 1e-9


@dataclass(frozen=True)
class Violation:
    """One limit a step exceeds: which limit, its value, the step's value, a sentence."""

    limit: str
    limit_value: float
    value: float
    message: str
    skippable: bool = True


def _over(value: float, limit: float) -> bool:
    return value > limit * (1.0 + _RTOL)


def _exceeds(limit: str, limit_value: float, value: float, what: str, unit: str,
             extra: str = "", skippable: bool = True) -> list[Violation]:
    if not _over(value, limit_value):
        return []
    msg = f"{what} {value:.6g} {unit} exceeds {limit} {limit_value:.6g} {unit}{extra}"
    return [Violation(limit, limit_value, value, msg, skippable)]


def _travel(axis: str, limits: AxisLimits, centre_deg: float,
            half_span_deg: float) -> list[Violation]:
    """Position stops of a non-continuous axis."""
    if limits.continuous:
        return []
    lo, hi = centre_deg - half_span_deg, centre_deg + half_span_deg
    out = _exceeds(f"{axis}.max_deg", limits.max_deg, hi, "position", "°")
    if lo < limits.min_deg - abs(limits.min_deg) * _RTOL:
        out.append(Violation(f"{axis}.min_deg", limits.min_deg, lo,
                             f"position {lo:.6g} ° is below {axis}.min_deg {limits.min_deg:.6g} °"))
    return out


def _sensor(accel_dps2: float, sheet: SensorDatasheet) -> list[Violation]:
    """Sensor test ceiling and noise floor for a peak acceleration the sensor will see."""
    ceiling = sheet.test_ceiling_fraction * sheet.range_dps2
    out = _exceeds("sensor.test_ceiling_dps2", ceiling, accel_dps2, "peak acceleration", "°/s²",
                   f" ({sheet.test_ceiling_fraction:.0%} of the {sheet.model} range)")
    if accel_dps2 < sheet.floor_dps2 * (1.0 - _RTOL):
        out.append(Violation("sensor.floor_dps2", sheet.floor_dps2, accel_dps2,
                             f"peak acceleration {accel_dps2:.6g} °/s² is below the sensor noise "
                             f"floor {sheet.floor_dps2:.6g} °/s²"))
    return out


def _sine(step: PlannedStep, env: TableEnvelope, sheet: SensorDatasheet) -> list[Violation]:
    axis = step.axis if step.axis in ("inner", "outer") else "inner"
    limits: AxisLimits = getattr(env, axis)
    freq_hz, amp_deg = float(step.frequency_hz or 0.0), float(step.amplitude_deg or 0.0)
    omega = 2.0 * math.pi * freq_hz
    terminal_hz = math.sqrt(limits.accel_dps2 / amp_deg) / (2.0 * math.pi) if amp_deg else math.inf
    out = _exceeds("max_frequency_hz", env.max_frequency_hz, freq_hz, "frequency", "Hz",
                   " (usable terminal frequency of the loaded table)")
    out += _exceeds(f"{axis}.rate_dps", limits.rate_dps, amp_deg * omega, "peak table rate", "°/s")
    out += _exceeds(f"{axis}.accel_dps2", limits.accel_dps2, amp_deg * omega**2,
                    "peak table acceleration", "°/s²",
                    f" (terminal frequency for A = {amp_deg:.6g}° is {terminal_hz:.6g} Hz)")
    centre = step.inner_deg if axis == "inner" else step.outer_deg
    return out + _travel(axis, limits, centre, amp_deg) + _sensor(amp_deg * omega**2, sheet)


def _constant_rate(step: PlannedStep, env: TableEnvelope,
                   sheet: SensorDatasheet) -> list[Violation]:
    if step.axis == "both":  # coordinated: rate_dps is the inner, outer_rate_dps the outer rate
        rates = {"inner": step.rate_dps, "outer": step.outer_rate_dps}
    else:
        rates = {"outer" if step.axis == "outer" else "inner": step.rate_dps}
    out: list[Violation] = []
    for axis, rate in rates.items():
        limits: AxisLimits = getattr(env, axis)
        out += _exceeds(f"{axis}.rate_dps", limits.rate_dps, abs(rate or 0.0), "table rate", "°/s")
        if not limits.continuous:
            out.append(Violation(f"{axis}.continuous", 0.0, abs(rate or 0.0),
                                 f"constant rate needs a continuous {axis} axis"))
    if step.accel_dps2 is not None:  # coordinated rates: the sensor sees ω_i·ω_o
        out += _sensor(step.accel_dps2, sheet)
    return out


def streams_record(step: PlannedStep, env: TableEnvelope) -> bool:
    """True when ``step`` is recorded by the streaming DAQ with the table's head: a static
    record longer than the table's log capacity on a rig whose DAQ streams."""
    return (step.kind == "static" and env.streaming_daq
            and step.samples > env.log_capacity_samples)


def head_step(step: PlannedStep, env: TableEnvelope) -> PlannedStep:
    """What the table logs during a streamed record: its full-rate log from the trigger on,
    as long as its log buffer holds (``log_capacity_samples``; the same rate as the DAQ).

    Why full rate, not snapshots: the freeze-pulse edges (100 Hz) are only in a log sampled
    faster than the pulse; the clocks are fitted on the edges both loggers hold and the fitted
    drift is carried over the rest of the record (docs/method.md §2, "partial table log").
    """
    samples = min(step.samples, env.log_capacity_samples)
    return step.model_copy(update={"samples": samples})


def _logger(step: PlannedStep, env: TableEnvelope) -> list[Violation]:
    out = _exceeds("max_log_rate_hz", env.max_log_rate_hz, step.sample_rate_hz, "sample rate",
                   "Hz", skippable=False)
    if streams_record(step, env):  # the DAQ streams; the table logs its head only
        return out
    hint = (" (controller log capacity; a static record this long needs a DAQ plugin that "
            "streams, docs/vendor-plugins.md)" if step.kind == "static"
            else " (controller log capacity)")
    return out + _exceeds("log_capacity_samples", env.log_capacity_samples, step.samples,
                          "record length", "samples", hint, False)


def _moved_axes(step: PlannedStep) -> set[str]:
    """The axes a step's motion drives (a static step drives none)."""
    if step.kind == "sine":
        return {step.axis if step.axis in ("inner", "outer") else "inner"}
    if step.kind == "constant_rate":
        if step.axis == "both" or step.outer_rate_dps:
            return {"inner", "outer"}
        return {"outer" if step.axis == "outer" else "inner"}
    return set()


def _absent_axes(step: PlannedStep, env: TableEnvelope) -> list[Violation]:
    """A step that moves or positions an axis the table does not have (``envelope.axes``):
    not skippable, whatever its limits would say."""
    moved, out = _moved_axes(step), []
    for axis in ("inner", "outer"):
        position = step.inner_deg if axis == "inner" else step.outer_deg
        if axis in env.axes or (axis not in moved and position == 0.0):
            continue
        action = (f"moves the {axis} axis" if axis in moved
                  else f"puts the {axis} axis at {position:g}°")
        out.append(Violation(f"{axis}.present", 0.0, 1.0,
                             f"the step {action}, an axis this table does not have "
                             f"(declared axes: {', '.join(env.axes)})", skippable=False))
    return out


def _set_point(step: PlannedStep, sheet: SensorDatasheet) -> list[Violation]:
    """A chamber set-point outside the temperatures the sensor may be taken to."""
    if step.temperature_c is None:
        return []
    low, high = sheet.operating_temperature_c
    value = float(step.temperature_c)
    if low <= value <= high:
        return []
    limit, bound = ("sensor.operating_temperature_c", high if value > high else low)
    side = "above" if value > high else "below"
    return [Violation(limit, bound, value,
                      f"chamber set-point {value:g} °C is {side} the {sheet.model}'s operating "
                      f"temperature range {low:g} to {high:g} °C", skippable=False)]


def step_violations(step: PlannedStep, envelope: TableEnvelope,
                    datasheet: SensorDatasheet) -> list[Violation]:
    """Every limit ``step`` exceeds (empty when it fits): a chamber step only its set-point
    against the sensor's operating temperatures."""
    if step.kind == "chamber":
        return _set_point(step, datasheet)
    if not step.recorded:
        return []
    out = _logger(step, envelope)
    absent = _absent_axes(step, envelope)
    if absent:  # the limits of a missing axis mean nothing: the reason is the axis itself
        return out + absent
    if step.kind == "sine":
        out += _sine(step, envelope, datasheet)
    elif step.kind == "constant_rate":
        out += _constant_rate(step, envelope, datasheet)
    out += _travel("inner", envelope.inner, step.inner_deg, 0.0)
    if "outer" not in envelope.axes:  # held at 0° (checked above): no stops to check
        return out
    return out + _travel("outer", envelope.outer, step.outer_deg, 0.0)


def file_locator(procedure_file: str) -> Callable[[YamlPath], tuple[int, int]]:
    """Map YAML paths to (line, column) in ``procedure_file``; (1, 1) if it cannot be read."""
    try:
        tree, _ = parse_yaml(read_text(Path(procedure_file)), procedure_file)
    except ProcedureError:
        tree = None
    return lambda path: locate_in_tree(tree, path) if tree is not None else (1, 1)


def check_envelope(plan: Plan, envelope: TableEnvelope, datasheet: SensorDatasheet,
                   procedure_file: str | None = None,
                   locate: Callable[[YamlPath], tuple[int, int]] | None = None,
                   sources: Mapping[str, YamlPath] | None = None) -> None:
    """Reject a plan that leaves the rig or sensor envelope.

    Parameters
    ----------
    plan : Plan
        From :func:`aatest.engine.procedure.planner.expand`.
    envelope : TableEnvelope
        The turntable plugin's limits (rates °/s, accelerations °/s², log rate Hz, samples).
    datasheet : SensorDatasheet
        The sensor plugin's datasheet (range, test ceiling fraction, noise floor in °/s²).
    procedure_file : str, optional
        File the plan came from; problems then carry the line and column of the step entry
        (or generator) that produced the offending step.
    locate : callable, optional
        YAML path → (line, column); defaults to reading ``procedure_file``.
    sources : mapping, optional
        Step id → YAML path; defaults to the table the planner kept for this plan.

    Raises
    ------
    EnvelopeError
        One :class:`Problem` per violation, naming the step id, the limit and the value.
    """
    if sources is None:
        trace = trace_of(plan)
        sources = trace.sources if trace is not None else {}
    if locate is None:
        locate = file_locator(procedure_file) if procedure_file else (lambda _path: (1, 1))
    filename = procedure_file or f"<{plan.procedure}>"
    by_source: dict[YamlPath, list[tuple[str, Violation]]] = {}
    for step in plan.steps:
        for v in step_violations(step, envelope, datasheet):
            by_source.setdefault(tuple(sources.get(step.id, ("steps",))), []).append((step.id, v))
    problems = []
    for source, found in by_source.items():
        line, col = locate(source)
        if len({step_id for step_id, _ in found}) == 1:
            problems += [Problem(filename, line, col, step_id, f"{v.message} [{v.limit}]")
                         for step_id, v in found]
        else:
            problems.append(Problem(filename, line, col, ".".join(map(str, source)),
                                    _grouped_message(found)))
    if problems:
        raise EnvelopeError(problems)


def _grouped_message(found: list[tuple[str, Violation]]) -> str:
    """One sentence for every step one YAML element produces that leaves the envelope: how
    many steps, their first and last ids, and per broken limit the count and the worst case."""
    ids = list(dict.fromkeys(step_id for step_id, _ in found))
    by_limit: dict[str, list[Violation]] = {}
    for _step_id, v in found:
        by_limit.setdefault(v.limit, []).append(v)
    parts = []
    for limit, violations in by_limit.items():
        worst = max(violations, key=lambda v: abs(v.value - v.limit_value))
        parts.append(f"{len(violations)} × [{limit}], worst: {worst.message}")
    return (f"{len(ids)} steps from this entry leave the envelope ({ids[0]} … {ids[-1]}): "
            + "; ".join(parts))


def describe(violations: list[Violation]) -> list[dict[str, Any]]:
    """JSON-able form of violations (used for the skipped-points list of a plan)."""
    return [{"limit": v.limit, "limit_value": v.limit_value, "value": v.value,
             "message": v.message} for v in violations]
