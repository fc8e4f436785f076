"""Pass/fail of every calibrated parameter against the datasheet (docs/method.md §1.3).

Decision rule: simple acceptance (ILAC-G8 "shared risk") — a value passes when its deviation
is within the limit; the margin (limit − |deviation|, in the parameter's unit and in % of the
limit) and the expanded uncertainty U are shown, and a verdict whose margin is smaller than
U is flagged so the reader knows the decision is within the measurement's reach.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from aatest.engine.datasheet import (
    REFERENCE_BIAS_V,
    REFERENCE_RANGE_DPS2,
    REFERENCE_SCALE_V_PER_DPS2,
)
from aatest.plugins.report import extract as ex

DPS2_PER_RAD_S2 = 57.29577951308232


@dataclass(frozen=True)
class Verdict:
    """One row of the pass/fail table."""

    parameter: str
    channel: str
    value: float
    nominal: float
    unit: str
    limit: float
    deviation: float
    margin: float
    expanded_uncertainty: float | None
    passed: bool

    @property
    def margin_pct(self) -> float:
        """Margin as a percentage of the limit (negative when outside)."""
        return 100.0 * self.margin / self.limit if self.limit else 0.0

    @property
    def within_uncertainty(self) -> bool:
        """True when U is larger than the margin: the decision is not clear-cut."""
        u = self.expanded_uncertainty
        return u is not None and u > abs(self.margin)

    @property
    def verdict(self) -> str:
        return "pass" if self.passed else "fail"


def _verdict(parameter: str, channel: str, value: float, nominal: float, unit: str,
             limit: float, u: float | None = None) -> Verdict:
    deviation = value - nominal
    margin = limit - abs(deviation)
    return Verdict(parameter, channel, value, nominal, unit, limit, deviation, margin, u,
                   margin >= 0)


def _limit(sensor: Mapping[str, Any], key: str, default: float) -> float:
    return ex.as_float(sensor.get(key)) or default


def _static_verdicts(results: Mapping[str, Any], ch: str, sensor: Mapping[str, Any],
                     u: Mapping[str, float]) -> list[Verdict]:
    rows: list[Verdict] = []
    bias = (ex.analysis(results, "bias") or {}).get(ch) or {}
    range_dps2 = _limit(sensor, "range_dps2", REFERENCE_RANGE_DPS2)
    if (b := ex.as_float(bias.get("bias_v"))) is not None:
        nominal_v = _limit(sensor, "nominal_bias_v", REFERENCE_BIAS_V)
        rows.append(_verdict("bias", ch, b, nominal_v, "V",
                             _limit(sensor, "bias_tolerance_v", 0.01), u.get(f"bias/{ch}")))
    if (g := ex.as_float(bias.get("g_sensitivity_dps2_per_g"))) is not None:
        # the analysis' own limit when stated, so report and results agree; else 0.1 % FR/g
        # or 0.01 rad/s²/g, whichever is greater (docs/method.md §1.3)
        g_limit = ex.as_float(bias.get("g_sensitivity_limit_dps2_per_g")) or max(
            0.001 * range_dps2, 0.01 * DPS2_PER_RAD_S2)
        rows.append(_verdict("g-sensitivity", ch, g, 0.0, "(°/s²)/g", g_limit,
                             u.get(f"g_sensitivity/{ch}")))
    scale = (ex.analysis(results, "scale_factor") or {}).get(ch) or {}
    if (k := ex.as_float(scale.get("scale_v_per_dps2"))) is not None:
        nominal = _limit(sensor, "nominal_scale_v_per_dps2", REFERENCE_SCALE_V_PER_DPS2)
        limit_pct = _limit(sensor, "scale_tolerance_pct", 1.0)
        u_k = u.get(f"scale_factor/{ch}")
        rows.append(_verdict("scale factor deviation", ch, 100.0 * (k / nominal - 1.0), 0.0, "%",
                             limit_pct, None if u_k is None else 100.0 * u_k / nominal))
    nl_pct = ex.as_float(scale.get("nonlinearity_pct_fr"))
    if nl_pct is None and (nl := ex.as_float(scale.get("nonlinearity_dps2"))) is not None:
        nl_pct = 100.0 * nl / range_dps2
    if nl_pct is not None:
        rows.append(_verdict("non-linearity", ch, nl_pct, 0.0, "% FR", 0.05))
    return rows


def _thermal_verdicts(results: Mapping[str, Any], ch: str, sensor: Mapping[str, Any],
                      u: Mapping[str, float]) -> list[Verdict]:
    rows: list[Verdict] = []
    temp = (ex.analysis(results, "temperature") or {}).get(ch) or {}
    if (c := ex.as_float(temp.get("bias_coefficient_v_per_c"))) is not None:
        rows.append(_verdict("bias temperature coefficient", ch, c, 0.0, "V/°C",
                             _limit(sensor, "bias_temperature_limit_v_per_c", 0.0004),
                             u.get(f"bias_coefficient_v_per_c/{ch}")))
    if (c := ex.as_float(temp.get("scale_coefficient_per_c"))) is not None:
        rows.append(_verdict("scale temperature coefficient", ch, c, 0.0, "1/°C",
                             _limit(sensor, "scale_temperature_limit_per_c", 0.0005),
                             u.get(f"scale_coefficient_per_c/{ch}")))
    noise = (ex.analysis(results, "noise") or {}).get(ch) or {}
    # the worst step decides, as in the noise analysis' own flag
    if (n := ex.as_float(noise.get("rms_max_v", noise.get("rms_v")))) is not None:
        limit = _limit(sensor, "noise_rms_v", 0.003)
        rows.append(_verdict("output noise (RMS)", ch, n, 0.0, "V", limit))
    return rows


def _misalignment_verdicts(results: Mapping[str, Any], u: Mapping[str, float]) -> list[Verdict]:
    block = ex.analysis(results, "misalignment") or {}
    rows: list[Verdict] = []
    for scenario, sensors in sorted((block.get("scenarios") or {}).items()):
        for sensor, entry in sorted((sensors or {}).items()):
            if (d := ex.as_float((entry or {}).get("delta_deg"))) is not None:
                rows.append(_verdict(f"misalignment (scenario {scenario})", sensor, d, 0.0, "deg",
                                     0.5, u.get(f"misalignment/{scenario}/{sensor}")))
    worst: dict[str, tuple[float, str]] = {}
    for label, sensors in sorted((block.get("sets") or {}).items()):
        for sensor, entry in sorted((sensors or {}).items()):
            for key in ("cross_ratio_x", "cross_ratio_y"):
                ratio = ex.as_float((entry or {}).get(key))
                if ratio is not None and ratio >= worst.get(sensor, (-1.0, ""))[0]:
                    worst[sensor] = (ratio, f"set {label}, {key[-1]}")
    for sensor, (ratio, where) in sorted(worst.items()):  # the worst set decides
        rows.append(_verdict(f"cross-axis ratio (worst: {where})", sensor, 100 * ratio, 0.0,
                             "%", 1.0))
    return rows


def verdicts(results: Mapping[str, Any], expanded: Mapping[str, float]) -> list[Verdict]:
    """Every parameter the results contain, judged against its datasheet limit.

    ``expanded`` maps ``"<quantity>/<channel>"`` to the expanded uncertainty U (k = 2) in the
    parameter's own unit (scale factor: V/(°/s²), converted here to %).
    """
    rows: list[Verdict] = []
    for ch, sensor in ex.sensors(results).items():
        rows += _static_verdicts(results, ch, sensor, expanded)
        rows += _thermal_verdicts(results, ch, sensor, expanded)
    return rows + _misalignment_verdicts(results, expanded)
