"""The sensor output each planned step asks for, against the stated logger's input range.

Why before anything moves: a logger whose range ends inside the sensor's output clips every
peak, and the run would record it all only to fail on the logger-rail verdict
(:mod:`aatest.metrology.logger_rails`). A step is refused when the *nominal* unit would reach a
rail: the datasheet's zero-acceleration output ± |nominal scale factor| × the step's peak
acceleration, within the rail tolerance of the verdict (one converter step plus the logger's
stated offset and gain accuracy). A unit that is off nominal but within its datasheet may
still clip; the verdict after the run says so.

Which logger: the rig description's ``instruments.logger``, else, on the twin's own logger
without a model file, the stated default (±10 V, 16 bit: the converter the twin quantises
with). A real logger nobody stated is not checked: its range is unknown.
"""

from __future__ import annotations

from typing import Any

from aatest.engine.errors import Problem
from aatest.engine.rig_description import LoggerSpec
from aatest.engine.run.rig import sensor_datasheet
from aatest.engine.steps import PlannedStep, SensorRef
from aatest.metrology.logger_rails import rail_tolerance_v, twin_logger_is_default
from aatest.positioned_yaml import locate


def checked_logger(rig_config: Any) -> LoggerSpec | None:
    """The logger the plan is checked against, None when the rig states none (see above)."""
    instruments = rig_config.instruments
    if instruments is not None and "logger" in instruments.model_fields_set:
        return instruments.logger
    daq = rig_config.daq
    if twin_logger_is_default({"rig": {"daq": {"plugin": daq.plugin, **(daq.options or {})}}}):
        return LoggerSpec()
    return None


def peak_accel_dps2(step: PlannedStep) -> float:
    """The largest acceleration the step commands, °/s² (a sine's peak; 0 at rest or at a
    constant rate)."""
    return abs(step.accel_dps2) if step.kind == "sine" and step.accel_dps2 is not None else 0.0


def logger_range_problems(prepared: Any) -> tuple[list[Problem], str]:
    """One located problem per procedure element whose steps would clip (see the module)."""
    logger = checked_logger(prepared.rig_config)
    if logger is None:
        return [], "not checked: the rig description states no logger (instruments.logger)"
    proc = prepared.procedure
    sheet = sensor_datasheet(SensorRef(model=proc.sensor.model))[0]
    low_v, high_v = logger.range_v
    floor_v, ceiling_v = (low_v + rail_tolerance_v(logger, low_v),
                          high_v - rail_tolerance_v(logger, high_v))
    clipping: dict[tuple[Any, ...], list[tuple[float, PlannedStep]]] = {}
    for step in prepared.plan.steps:
        if not step.recorded:
            continue
        swing_v = abs(sheet.nominal_scale_v_per_dps2) * peak_accel_dps2(step)
        over_v = max(sheet.nominal_bias_v + swing_v - ceiling_v,
                     floor_v - (sheet.nominal_bias_v - swing_v))
        if over_v >= 0.0:
            path = tuple(prepared.expansion.sources.get(step.id, ("steps",)))
            clipping.setdefault(path, []).append((over_v, step))
    message = (f"the sensor's nominal output stays inside the logger's {low_v:g}…{high_v:g} V "
               f"(rails less {rail_tolerance_v(logger, high_v) * 1e3:.2f} mV)")
    filename = proc.source_file or f"<{proc.procedure}>"
    problems = []
    for path, found in clipping.items():
        _over, worst = max(found, key=lambda item: item[0])
        line, column = locate(proc.source_tree, path) if proc.source_tree is not None else (1, 1)
        problems.append(Problem(filename, line, column, ".".join(map(str, path)),
                                _clips(worst, len(found), sheet, logger)))
    return problems, message if not problems else "a planned step would clip at the logger"


def _clips(step: PlannedStep, count: int, sheet: Any, logger: LoggerSpec) -> str:
    swing_v = abs(sheet.nominal_scale_v_per_dps2) * peak_accel_dps2(step)
    low_v, high_v = logger.range_v
    steps = f"{count} steps, the worst" if count > 1 else "step"
    return (f"{steps} {step.id} asks {peak_accel_dps2(step):g} °/s²: the nominal {sheet.model} "
            f"puts out {sheet.nominal_bias_v - swing_v:.3g}…{sheet.nominal_bias_v + swing_v:.3g} V "
            f"({sheet.nominal_bias_v:g} V ± {abs(sheet.nominal_scale_v_per_dps2):g} V/(°/s²) × "
            f"{peak_accel_dps2(step):g} °/s²), beyond the logger's input range {low_v:g}…"
            f"{high_v:g} V (instruments.logger): it would clip the output; give the logger a "
            "range with headroom, or ask less acceleration")
