"""What a record keeps from the typed results: the key quantities, the verdicts, the unit.

Reads :class:`aatest.results.RunResults` by attribute. Expanded uncertainties and verdicts are
only taken when the results carry them: nothing is estimated here, so a record never states an
uncertainty the analysis did not. Names are ``QUANTITY.CHANNEL`` with ``QUANTITY`` a key of
the quantity registry (:mod:`aatest.results.quantities`), which also gives each its unit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from aatest.results import RunResults
from aatest.results.quantities import QUANTITIES, finite

FRF_GAIN = "frf_gain"


@dataclass(frozen=True)
class Quantity:
    """One key result of a calibration: ``value ± expanded_uncertainty`` in ``unit``."""

    name: str
    value: float
    expanded_uncertainty: float | None
    unit: str


def _unit(key: str) -> str:
    return QUANTITIES[key].unit


def _scalar_quantities(results: RunResults) -> list[Quantity]:
    found = []
    scale, bias = results.analysis.scale_factor, results.analysis.bias
    for channel, entry in (scale.items() if scale else []):
        if (value := finite(entry.scale_v_per_dps2)) is not None:
            found.append(Quantity(f"scale_factor.{channel}", value,
                                  finite(entry.expanded_uncertainty), _unit("scale_factor")))
    for channel, entry in (bias.items() if bias else []):
        if (value := finite(entry.bias_v)) is not None:
            found.append(Quantity(f"bias.{channel}", value, finite(entry.expanded_uncertainty),
                                  _unit("bias")))
    for channel, entry in (bias.items() if bias else []):
        if (value := finite(entry.g_sensitivity_dps2_per_g)) is not None:
            found.append(Quantity(f"g_sensitivity.{channel}", value, None,
                                  _unit("g_sensitivity")))
    return found


def _frf_quantities(results: RunResults, reference_hz: float) -> list[Quantity]:
    found = []
    frf = results.analysis.frf
    for channel, points in (frf.items() if frf else []):
        rows = [p for p in points if finite(p.gain_db) is not None and finite(p.frequency_hz)]
        if not rows:
            continue
        nearest = min(rows, key=lambda p: abs(math.log(p.frequency_hz / reference_hz)))
        found.append(Quantity(f"{FRF_GAIN}.{channel}", nearest.gain_db,
                              finite(nearest.gain_expanded_uncertainty_db), _unit(FRF_GAIN)))
    return found


def key_quantities(results: RunResults, frf_reference_hz: float = 1.0) -> list[Quantity]:
    """Scale factor, bias, g-sensitivity and the FRF gain nearest ``frf_reference_hz``.

    Names are ``QUANTITY.CHANNEL`` (``scale_factor.v_sz``); absent analyses give no entry.
    """
    return _scalar_quantities(results) + _frf_quantities(results, frf_reference_hz)


def verdict_rows(results: RunResults) -> list[dict[str, Any]]:
    """The verdicts as the records store keeps them (their results.json form)."""
    return [v.model_dump(mode="json") for v in results.verdicts]


def unit_of(results: RunResults) -> tuple[str, str]:
    """``(sensor model, serial)`` of the calibrated unit, from the run metadata
    (:meth:`~aatest.results.root.RunMetadata.unit`)."""
    unit = results.metadata.unit()
    return unit.model or "unknown", unit.serial or "unspecified"


def datasheet_limits(results: RunResults) -> dict[str, tuple[float, float]]:
    """Acceptance band ``(low, high)`` per key quantity from the sensor datasheet in the run.

    Scale factor: nominal ± tolerance %; bias: nominal ± tolerance V; g-sensitivity: ±limit
    when the bias analysis states one. Quantities without a datasheet limit are left out.
    """
    limits: dict[str, tuple[float, float]] = {}
    for sensor in results.metadata.sensors:
        nominal = sensor.nominal_scale_v_per_dps2
        half = abs(nominal) * sensor.scale_tolerance_pct / 100.0
        limits[f"scale_factor.{sensor.channel}"] = (nominal - half, nominal + half)
        limits[f"bias.{sensor.channel}"] = (sensor.nominal_bias_v - sensor.bias_tolerance_v,
                                           sensor.nominal_bias_v + sensor.bias_tolerance_v)
    bias = results.analysis.bias
    for channel, entry in (bias.items() if bias else []):
        if (g_limit := finite(entry.g_sensitivity_limit_dps2_per_g)) is not None:
            limits[f"g_sensitivity.{channel}"] = (-g_limit, g_limit)
    return limits
