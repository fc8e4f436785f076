"""Static multi-position test: bias and g-sensitivity (docs/method.md §4.1).

Each static step gives the mean output of every sensor and the specific force of gravity along
its axis (from the commanded table orientation; docs/interfaces.md §4 "Gravity"). Per sensor and
mounting (original / pivoted) and repetition, the up (A+) and down (A−) means give
K0 = (A+ + A−)/2 and the g-sensitivity (A+ − A−)/2 divided by the scale factor. A straight-line
fit V = b + k·g over *all* positions (horizontal ones too) is reported alongside, with its
residual as a check of the positions. Datasheet flags: bias band and the linear-acceleration
limit (0.1 % FR/g or 0.01 rad/s²/g, whichever is greater).
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np

from aatest.clocksync.freeze_pulse import SyncedStep
from aatest.engine.interfaces import AnalysisContext, AnalysisOutput, NoOptions
from aatest.engine.requirements import Requirement
from aatest.plugins.analysis import needs
from aatest.plugins.analysis._common import scale_in_use, steps_of, t95
from aatest.plugins.analysis.geometry import gravity_along_g
from aatest.plugins.analysis.streaming import reduce_static
from aatest.recording.dataset import Dataset, SensorInfo
from aatest.results.bias import BiasResult

_UP_G = 0.9  # |g component| above which a position counts as "axis up/down"
_RAD_DPS2 = float(np.degrees(1.0))

#: positions a bias line (bias against gravity component) needs; also the set-points that make
#: the bias a per-set-point result
_MIN_LINE_POINTS = 2
#: the reference temperature the headline bias is stated at, °C
T_REF_C = 25.0


def g_sensitivity_limit(sensor: SensorInfo) -> float:
    """Datasheet linear-acceleration limit, °/s² per g."""
    return max(0.001 * 2 * sensor.range_dps2, 0.01 * _RAD_DPS2)


def _pair_stats(means: dict[int, dict[str, list[float]]], scale: float) -> dict[str, Any]:
    """K0 and g-sensitivity per repetition from the up/down means, and their spread."""
    k0, gs = [], []
    for rep in sorted(means):
        up, down = means[rep]["up"], means[rep]["down"]
        if up and down:
            a_p, a_m = float(np.mean(up)), float(np.mean(down))
            k0.append(0.5 * (a_p + a_m))
            gs.append(0.5 * (a_p - a_m) / scale)
    if not k0:
        return {}
    n = len(k0)
    spread = float(np.std(k0, ddof=1)) if n > 1 else 0.0
    g_spread = float(np.std(gs, ddof=1)) if n > 1 else 0.0
    return {
        "bias_v": float(np.mean(k0)), "bias_u_v": spread / np.sqrt(n),
        "bias_spread_v": spread, "bias_ci95_halfwidth_v": t95(n - 1) * spread / np.sqrt(n),
        "g_sensitivity_dps2_per_g": float(np.mean(gs)), "g_sensitivity_u_dps2_per_g":
        g_spread / np.sqrt(n), "repetitions": n, "per_repetition_bias_v": k0,
    }


def _line_fit(g: list[float], v: list[float]) -> dict[str, float]:
    """V = b + k·g over every position, with the residual RMS (V)."""
    design = np.column_stack([np.ones(len(g)), g])
    coef, *_ = np.linalg.lstsq(design, np.asarray(v), rcond=None)
    resid = np.asarray(v) - design @ coef
    return {"bias_v": float(coef[0]), "g_slope_v_per_g": float(coef[1]),
            "residual_rms_v": float(np.sqrt(np.mean(resid**2)))}


def sensor_bias(steps: Sequence[SyncedStep], sensor: SensorInfo, scale: float) -> dict[str, Any]:
    """Bias results of one sensor, overall and per mounting."""
    by_mount: dict[str, dict[int, dict[str, list[float]]]] = defaultdict(
        lambda: defaultdict(lambda: {"up": [], "down": []}))
    lines: dict[str, tuple[list[float], list[float]]] = defaultdict(lambda: ([], []))
    for s in steps:
        g = gravity_along_g(sensor.axis, s.step.inner_deg, s.step.outer_deg)
        mean_v = reduce_static(s.daq_blocks([sensor.channel]), [sensor.channel],
                               s.sample_rate_hz, len(s))[sensor.channel].moments.mean
        mount = "pivoted" if s.step.mounting.pivoted else "original"
        lines[mount][0].append(g)
        lines[mount][1].append(mean_v)
        if abs(g) >= _UP_G:
            by_mount[mount][s.step.repetition]["up" if g > 0 else "down"].append(mean_v)
    mountings = {m: _pair_stats(by_mount[m], scale) | {"line": _line_fit(*lines[m])}
                 for m in lines if len(lines[m][0]) >= _MIN_LINE_POINTS}
    paired = [r for r in mountings.values() if "bias_v" in r]
    if not paired:
        return {"mountings": mountings}
    bias = float(np.mean([r["bias_v"] for r in paired]))
    g_sens = float(np.mean([r["g_sensitivity_dps2_per_g"] for r in paired]))
    return {
        "bias_v": bias, "g_sensitivity_dps2_per_g": g_sens,
        "bias_u_v": float(np.sqrt(np.mean([r["bias_u_v"] ** 2 for r in paired]))),
        "scale_v_per_dps2_used": scale,
        "g_sensitivity_limit_dps2_per_g": g_sensitivity_limit(sensor),
        "mountings": mountings,
    }


class BiasAnalysis:
    """Bias K0 and g-sensitivity of every sensor from the static positions.

    Requires only ``sync``: the g-sensitivity is converted to °/s² with the datasheet scale
    factor (a 1 % scale error is irrelevant next to its limit), so a static-only procedure
    needs no sine calibration and the bias never depends on which analyses ran.
    """

    key: ClassVar[str] = "bias"
    requires: ClassVar[tuple[str, ...]] = ("sync",)
    #: what the plan must hold (checked by ``validate``; aatest.engine.requirements)
    requirements: ClassVar[tuple[Requirement, ...]] = needs.BIAS
    #: the acceptance quantities it produces (judged when it is listed)
    judges: ClassVar[tuple[str, ...]] = ("bias_deviation_v", "g_sensitivity_dps2_per_g")
    Options: ClassVar[type[NoOptions]] = NoOptions
    Result: ClassVar[type[BiasResult]] = BiasResult

    def applies_to(self, data: Dataset) -> bool:
        return any(p.kind == "static" for p in data.planned)

    def run(self, data: Dataset, context: AnalysisContext) -> AnalysisOutput[BiasResult]:
        static = steps_of(context, "static")
        values = {sensor.channel: bias_by_setpoint(static, sensor, scale_in_use(context, sensor))
                  for sensor in data.sensors}
        return AnalysisOutput(BiasResult.model_validate(values))


def bias_by_setpoint(steps: Sequence[SyncedStep], sensor: SensorInfo, scale: float
                     ) -> dict[str, Any]:
    """The bias of one sensor; with static records at several chamber set-points, per
    set-point (never mixing temperatures), the headline at the one nearest 25 °C."""
    temps = sorted({s.step.temperature_c for s in steps if s.step.temperature_c is not None})
    if len(temps) < _MIN_LINE_POINTS:
        return sensor_bias(steps, sensor, scale)
    per = {t: sensor_bias([s for s in steps if s.step.temperature_c == t], sensor, scale)
           | {"temperature_c": t} for t in temps}
    measured = [t for t in temps if per[t].get("bias_v") is not None] or temps
    head = min(measured, key=lambda t: abs(t - T_REF_C))
    return per[head] | {"setpoints": [per[t] for t in temps if per[t].get("bias_v") is not None]}
