"""Where acceptance limits come from: the sensor's datasheet, overridden by the procedure.

One source of limits (docs/method.md §1.3): the sensor plugin's
:class:`~aatest.engine.interfaces.SensorDatasheet` for recorded runs, the datasheet values of
``dataset.yaml`` for imported data, each overridable by the procedure's ``acceptance.limits``.
The quantity names are the limit names of :class:`~aatest.engine.procedure.models.AcceptanceLimits`.
"""

from __future__ import annotations

import math

from aatest.engine.interfaces import SensorDatasheet
from aatest.engine.procedure.models import Acceptance
from aatest.recording.dataset import SensorInfo
from aatest.results.quantities import QUANTITIES

#: 0.01 rad/s² in °/s²
DPS2_PER_RAD_S2 = math.degrees(1.0)

#: the judged quantities (limit names of the procedure's ``acceptance.limits``)
JUDGED = ("scale_factor_deviation_pct", "bias_deviation_v", "nonlinearity_pct_fr",
          "g_sensitivity_dps2_per_g", "cross_axis_ratio", "misalignment_deg",
          "bias_temperature_v_per_c", "scale_temperature_per_c", "noise_rms_v")
#: judged quantity → unit of its value, limit and expanded uncertainty in results.json
QUANTITY_UNITS: dict[str, str] = {k: QUANTITIES[k].json_unit for k in JUDGED}


def g_sensitivity_limit_dps2_per_g(sheet: SensorDatasheet) -> float:
    """The datasheet's linear-acceleration limit in (°/s²)/g.

    Stated by the sensor plugin, else 0.1 % FR/g or 0.01 rad/s²/g, whichever is greater
    (docs/method.md §1.3). FR is the full span of the ±``range_dps2`` input range, as in the
    non-linearity's % FR: with FR = range the two terms would be equal for the reference sensor
    and "whichever is greater" would mean nothing (the reference sensor: 1.146 (°/s²)/g).
    """
    if sheet.g_sensitivity_limit_dps2_per_g is not None:
        return sheet.g_sensitivity_limit_dps2_per_g
    return max(0.001 * 2.0 * sheet.range_dps2, 0.01 * DPS2_PER_RAD_S2)


def datasheet_limits(sheet: SensorDatasheet) -> dict[str, float]:
    """Every acceptance limit as the datasheet states it, by quantity name.

    Each limit is in the unit its name carries (``_pct`` in %, ``_v`` in V, ``_dps2_per_g``
    in (°/s²)/g, ``_per_c`` in 1/°C, ``_deg`` in °; a ``_ratio`` is dimensionless).
    """
    return {
        "scale_factor_deviation_pct": sheet.scale_tolerance_pct,
        "bias_deviation_v": sheet.bias_tolerance_v,
        "nonlinearity_pct_fr": sheet.nonlinearity_limit_pct_fr,
        "g_sensitivity_dps2_per_g": g_sensitivity_limit_dps2_per_g(sheet),
        "cross_axis_ratio": sheet.cross_axis_limit,
        "misalignment_deg": sheet.misalignment_limit_deg,
        "bias_temperature_v_per_c": sheet.bias_temperature_limit_v_per_c,
        "scale_temperature_per_c": sheet.scale_temperature_limit_per_c,
        "noise_rms_v": sheet.noise_rms_v,
    }


def limits(sheet: SensorDatasheet, acceptance: Acceptance) -> dict[str, float]:
    """The datasheet's limits with the procedure's overrides applied.

    Units as in :func:`datasheet_limits` (each in its name's unit: %, V, °, (°/s²)/g, 1/°C;
    ratios dimensionless).
    """
    overrides = acceptance.limits.model_dump(exclude_none=True)
    return datasheet_limits(sheet) | overrides


def datasheet_from_info(info: SensorInfo) -> SensorDatasheet:
    """A datasheet from one channel's stated values (imported data); other limits default."""
    return SensorDatasheet(
        model=info.model, range_dps2=info.range_dps2, nominal_bias_v=info.nominal_bias_v,
        bias_tolerance_v=info.bias_tolerance_v,
        nominal_scale_v_per_dps2=info.nominal_scale_v_per_dps2,
        scale_tolerance_pct=info.scale_tolerance_pct, noise_rms_v=info.noise_rms_v,
        bias_temperature_limit_v_per_c=info.bias_temperature_limit_v_per_c,
        scale_temperature_limit_per_c=info.scale_temperature_limit_per_c,
        channels={info.channel: info.axis},
    )
