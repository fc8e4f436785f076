"""What a record keeps from ``results.json``: the key quantities, the verdicts, the unit.

``results.json`` is read as a dict with the documented keys (docs/interfaces.md §1). Expanded
uncertainties and verdicts are only taken when the results carry them: nothing is estimated
here, so a record never states an uncertainty the analysis did not.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

#: key quantity → (analysis, value key, expanded-uncertainty key, unit)
_SCALARS: dict[str, tuple[str, str, str | None, str]] = {
    "scale_factor": ("scale_factor", "scale_v_per_dps2", "expanded_uncertainty", "V/(°/s²)"),
    "bias": ("bias", "bias_v", "expanded_uncertainty", "V"),
    "g_sensitivity": ("bias", "g_sensitivity_dps2_per_g", None, "(°/s²)/g"),
}
FRF_GAIN = "frf_gain"


@dataclass(frozen=True)
class Quantity:
    """One key result of a calibration: ``value ± expanded_uncertainty`` in ``unit``."""

    name: str
    value: float
    expanded_uncertainty: float | None
    unit: str


def _finite(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    return float(value) if math.isfinite(value) else None


def _channels(results: Mapping[str, Any], analysis: str) -> Mapping[str, Any]:
    block = (results.get("analysis") or {}).get(analysis)
    return block if isinstance(block, Mapping) else {}


def _scalar_quantities(results: Mapping[str, Any]) -> list[Quantity]:
    found = []
    for name, (analysis, key, u_key, unit) in _SCALARS.items():
        for channel, row in _channels(results, analysis).items():
            value = _finite(row.get(key)) if isinstance(row, Mapping) else None
            if value is not None:
                u = _finite(row.get(u_key)) if u_key else None
                found.append(Quantity(f"{name}.{channel}", value, u, unit))
    return found


def _frf_quantities(results: Mapping[str, Any], reference_hz: float) -> list[Quantity]:
    found = []
    for channel, points in _channels(results, "frf").items():
        rows = [p for p in points or [] if isinstance(p, Mapping)
                and _finite(p.get("gain_db")) is not None and _finite(p.get("frequency_hz"))]
        if not rows:
            continue
        nearest = min(rows, key=lambda p: abs(math.log(float(p["frequency_hz"]) / reference_hz)))
        u = _finite(nearest.get("gain_expanded_uncertainty_db"))
        found.append(Quantity(f"{FRF_GAIN}.{channel}", float(nearest["gain_db"]), u, "dB"))
    return found


def key_quantities(results: Mapping[str, Any], frf_reference_hz: float = 1.0) -> list[Quantity]:
    """Scale factor, bias, g-sensitivity and the FRF gain nearest ``frf_reference_hz``.

    Names are ``QUANTITY.CHANNEL`` (``scale_factor.v_sz``); absent analyses give no entry.
    """
    return _scalar_quantities(results) + _frf_quantities(results, frf_reference_hz)


def overall_verdict(results: Mapping[str, Any]) -> str:
    """``results["overall"]`` when judged, else ``none`` (nothing was judged)."""
    overall = results.get("overall")
    return str(overall) if isinstance(overall, str) and overall else "none"


def verdict_rows(results: Mapping[str, Any]) -> list[dict[str, Any]]:
    """The ``verdicts`` list as stored (empty when the results carry none)."""
    rows = results.get("verdicts")
    return [dict(r) for r in rows if isinstance(r, Mapping)] if isinstance(rows, list) else []


def unit_of(results: Mapping[str, Any]) -> tuple[str, str]:
    """``(sensor model, serial)`` of the calibrated unit, from the run metadata."""
    sensor = (results.get("metadata") or {}).get("sensor") or {}
    model = str(sensor.get("model") or "unknown")
    serial = sensor.get("serial")
    return model, str(serial) if serial else "unspecified"


def _sensor_rows(results: Mapping[str, Any]) -> list[Mapping[str, Any]]:
    rows = (results.get("metadata") or {}).get("sensors") or []
    return [r for r in rows if isinstance(r, Mapping) and r.get("channel")]


def datasheet_limits(results: Mapping[str, Any]) -> dict[str, tuple[float, float]]:
    """Acceptance band ``(low, high)`` per key quantity from the sensor datasheet in the run.

    Scale factor: nominal ± tolerance %; bias: nominal ± tolerance V; g-sensitivity: ±limit
    when the bias analysis states one. Quantities without a datasheet limit are left out.
    """
    limits: dict[str, tuple[float, float]] = {}
    for row in _sensor_rows(results):
        channel = str(row["channel"])
        nominal, tol = _finite(row.get("nominal_scale_v_per_dps2")), _finite(
            row.get("scale_tolerance_pct"))
        if nominal is not None and tol is not None:
            half = abs(nominal) * tol / 100.0
            limits[f"scale_factor.{channel}"] = (nominal - half, nominal + half)
        bias, bias_tol = _finite(row.get("nominal_bias_v")), _finite(row.get("bias_tolerance_v"))
        if bias is not None and bias_tol is not None:
            limits[f"bias.{channel}"] = (bias - bias_tol, bias + bias_tol)
    for channel, row in _channels(results, "bias").items():
        g_limit = _finite(row.get("g_sensitivity_limit_dps2_per_g")) if isinstance(
            row, Mapping) else None
        if g_limit is not None:
            limits[f"g_sensitivity.{channel}"] = (-g_limit, g_limit)
    return limits
