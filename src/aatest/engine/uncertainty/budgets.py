"""The uncertainty stage: evaluate every certified result's budget and write it into the results.

Runs after the analyses and before the verdicts (which read the expanded uncertainties written
here). Every quantity is propagated by the GUM law with k = 2 (:mod:`.gum`) through the
measurement models of :mod:`.measurands` and :mod:`.dynamic`; what each writes is listed in
:func:`apply_uncertainty`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from aatest.engine.uncertainty import access as ex
from aatest.engine.uncertainty.dynamic import (
    frf_gain_measurand,
    frf_phase_measurand,
    misalignment_measurand,
)
from aatest.engine.uncertainty.gum import Evaluation, Measurand, evaluate
from aatest.engine.uncertainty.measurands import (
    RigConstants,
    bias_measurand,
    g_sensitivity_measurand,
    scale_factor_measurand,
    temperature_measurand,
)

#: the analyses whose per-channel results name sensor channels
_CHANNEL_BLOCKS = ("scale_factor", "bias", "frf", "temperature", "transfer_function", "noise")


def channels(results: Mapping[str, Any]) -> list[str]:
    """Sensor channels: metadata order first, then any channel only the analyses name."""
    names = list(ex.sensors(results))
    for key in _CHANNEL_BLOCKS:
        block = ex.analysis(results, key)
        if isinstance(block, Mapping):
            names += [str(ch) for ch in block if str(ch) not in names]
    return names


def _evaluated(measurand: Measurand | None, results: dict[str, Any]) -> Evaluation | None:
    """The GUM evaluation of ``measurand``; None (with the reason in ``analysis_errors``) when
    its model cannot be evaluated in floating point (inputs such as ``accel_dps2: 1e-308``
    make the sensitivities overflow): the quantity then has no U and is not judged."""
    if measurand is None:
        return None
    try:
        return evaluate(measurand)
    except (OverflowError, ZeroDivisionError, ValueError) as exc:
        errors = results.setdefault("analysis_errors", {})
        errors["uncertainty"] = "; ".join(filter(None, [
            errors.get("uncertainty"), f"{measurand.name}: not evaluable ({exc})"]))
        return None


def _certify_static(results: dict[str, Any], ch: str, c: RigConstants) -> None:
    """Scale factor, bias (with g-sensitivity) and temperature coefficients of one channel."""
    scale = _evaluated(scale_factor_measurand(results, ch, c), results)
    scale_rel = None
    if scale is not None:
        ex.certify(ex.channel_entry(results, "scale_factor", ch), scale)
        scale_rel = scale.standard_uncertainty / abs(scale.value) if scale.value else None
    bias = _evaluated(bias_measurand(results, ch, c), results)
    if bias is not None:
        ex.certify(ex.channel_entry(results, "bias", ch), bias)
    g_sens = _evaluated(g_sensitivity_measurand(results, ch, c, scale_rel), results)
    if g_sens is not None:
        ex.certify(ex.channel_entry(results, "bias", ch), g_sens, "g_sensitivity", "_dps2_per_g")
    temperature = ex.channel_entry(results, "temperature", ch)
    bias_tc = _evaluated(temperature_measurand(results, ch, "bias_coefficient_v_per_c", c), results)
    if bias_tc is not None:
        ex.certify(temperature, bias_tc)
    scale_tc = _evaluated(temperature_measurand(results, ch, "scale_coefficient_per_c", c), results)
    if scale_tc is not None:
        ex.certify(temperature, scale_tc, "scale_coefficient", "_per_c")


def _certify_frf(results: dict[str, Any], ch: str, c: RigConstants) -> None:
    """Gain (the generic fields, and ``gain_*``) and phase (``phase_*``) of every FRF point."""
    for point in ex.frf_points(results, ch):
        gain = _evaluated(frf_gain_measurand(point, results, c, ch), results)
        if gain is not None:
            ex.certify(point, gain)
            ex.certify(point, gain, "gain", "_db")
        phase = _evaluated(frf_phase_measurand(point, results, c, ch), results)
        if phase is not None:
            ex.certify(point, phase, "phase", "_deg")
            point["phase_coverage_factor"] = phase.k  # the generic k is the gain's


def apply_uncertainty(results: dict[str, Any], constants: RigConstants | None = None,
                      data: Any = None) -> dict[str, Any]:
    """Evaluate and write the uncertainty of every certified result (GUM, k = 2), in place.

    Writes the fields of :class:`aatest.results.base.Certified` (``expanded_uncertainty``,
    ``coverage_factor``, ``coverage_probability``, ``budget``) into ``analysis.scale_factor[CH]``,
    ``analysis.bias[CH]`` (bias; g-sensitivity as ``g_sensitivity_expanded_uncertainty_dps2_per_g``
    and ``g_sensitivity_budget``), ``analysis.temperature[CH]`` (bias coefficient; scale
    coefficient as ``scale_coefficient_*``), every point of ``analysis.frf[CH]`` (gain, plus
    ``gain_*``/``phase_*``) and ``analysis.misalignment.scenarios[S][SENSOR]``.

    Parameters
    ----------
    results
        The results document (today's ``results.json`` shape); changed in place and returned.
    constants
        The rig's stated accuracies (default: the run's rig description in its metadata,
        else the documented rig, docs/method.md §1.2, named as defaults in every basis).
    data
        The dataset the analyses ran on; the components the logs show (motion distortion,
        logged temperature) are measured from it (None: those rows say "not evaluated").
    """
    c = constants if constants is not None else RigConstants.from_results(results, data)
    metadata = results.setdefault("metadata", {})
    if isinstance(metadata, dict):  # the certificate states the reference's traceability
        metadata["traceability"] = {
            "stated": c.instruments_stated,
            "instruments": c.instruments.traceability(),
            "reference_temperature_c": c.instruments.lab.reference_temperature_c,
        }
    for ch in channels(results):
        _certify_static(results, ch, c)
        _certify_frf(results, ch, c)
    for scenario, sensors in ex.misalignment_scenarios(results).items():
        for sensor, entry in sorted(sensors.items()):
            evaluation = _evaluated(misalignment_measurand(results, scenario, sensor, c), results)
            if evaluation is not None:
                ex.certify(entry, evaluation)
    return results
