"""The uncertainty stage: evaluate every certified result's budget and write it into the results.

Runs after the analyses and before the verdicts (which read the expanded uncertainties written
here). Every quantity is propagated by the GUM law with k = 2 (:mod:`.gum`) through the
measurement models of :mod:`.measurands` and :mod:`.dynamic`; what each writes is listed in
:func:`apply_uncertainty`.
"""

from __future__ import annotations

from typing import Any

from aatest.metrology.uncertainty.clock_window import noise_measurand
from aatest.metrology.uncertainty.dynamic import (
    frf_gain_measurand,
    frf_phase_measurand,
    misalignment_measurand,
    sensor_tilt_measurand,
)
from aatest.metrology.uncertainty.gum import Evaluation, Measurand, evaluate
from aatest.metrology.uncertainty.measurands import (
    RigConstants,
    bias_measurand,
    g_sensitivity_measurand,
    scale_factor_measurand,
    temperature_measurand,
)
from aatest.results import BudgetRow, Certified, RunResults
from aatest.results.root import InstrumentTrace, ReferenceTraceability


def channels(results: RunResults) -> list[str]:
    """Sensor channels: metadata order first, then any channel only the analyses name."""
    names = [s.channel for s in results.metadata.sensors]
    a = results.analysis
    for block in (a.scale_factor, a.bias, a.frf, a.temperature, a.transfer_function, a.noise):
        names += [ch for ch in (block or ()) if ch not in names]
    return names


def _evaluated(measurand: Measurand | None, results: RunResults) -> Evaluation | None:
    """The GUM evaluation of ``measurand``; None (with the reason in ``analysis_errors``) when
    its model cannot be evaluated in floating point (inputs such as ``accel_dps2: 1e-308``
    make the sensitivities overflow): the quantity then has no U and is not judged."""
    if measurand is None:
        return None
    try:
        return evaluate(measurand)
    except (OverflowError, ZeroDivisionError, ValueError) as exc:
        errors = results.analysis_errors
        errors["uncertainty"] = "; ".join(filter(None, [
            errors.get("uncertainty"), f"{measurand.name}: not evaluable ({exc})"]))
        return None


def _rows(evaluation: Evaluation) -> list[BudgetRow]:
    return list(evaluation.rows)


def certify(entry: Certified, evaluation: Evaluation) -> None:
    """Write an evaluation's U, k, coverage probability, budget and measurand into a result."""
    entry.expanded_uncertainty = evaluation.expanded_uncertainty
    entry.coverage_factor = evaluation.k
    entry.coverage_probability = evaluation.coverage_probability
    entry.budget = _rows(evaluation)
    entry.measurand = evaluation.definition


def _certify_static(results: RunResults, ch: str, c: RigConstants) -> None:
    """Scale factor, bias (with g-sensitivity) and temperature coefficients of one channel."""
    a = results.analysis
    scale = _evaluated(scale_factor_measurand(results, ch, c), results)
    scale_rel = None
    if scale is not None and a.scale_factor is not None:
        certify(a.scale_factor[ch], scale)
        scale_rel = scale.standard_uncertainty / abs(scale.value) if scale.value else None
        for level in a.scale_factor[ch].levels:  # each level certified like the headline
            if (evaluated := _evaluated(scale_factor_measurand(results, ch, c, level), results)):
                certify(level, evaluated)
    bias = _evaluated(bias_measurand(results, ch, c), results)
    if bias is not None and a.bias is not None:
        certify(a.bias[ch], bias)
        for setpoint in a.bias[ch].setpoints:  # each set-point certified like the headline
            if (evaluated := _evaluated(bias_measurand(results, ch, c, setpoint), results)):
                certify(setpoint, evaluated)
    g_sens = _evaluated(g_sensitivity_measurand(results, ch, c, scale_rel), results)
    if g_sens is not None and a.bias is not None:
        entry = a.bias[ch]
        entry.g_sensitivity_expanded_uncertainty_dps2_per_g = g_sens.expanded_uncertainty
        entry.g_sensitivity_budget = _rows(g_sens)
        entry.g_sensitivity_measurand = g_sens.definition
    noise = _evaluated(noise_measurand(results, ch, c), results)
    if noise is not None and a.noise is not None:
        certify(a.noise[ch], noise)
    bias_tc = _evaluated(temperature_measurand(results, ch, "bias_coefficient_v_per_c", c),
                        results)
    if bias_tc is not None and a.temperature is not None:
        certify(a.temperature[ch], bias_tc)
    scale_tc = _evaluated(temperature_measurand(results, ch, "scale_coefficient_per_c", c),
                         results)
    if scale_tc is not None and a.temperature is not None:
        temperature = a.temperature[ch]
        temperature.scale_coefficient_expanded_uncertainty_per_c = scale_tc.expanded_uncertainty
        temperature.scale_coefficient_budget = _rows(scale_tc)
        temperature.scale_coefficient_measurand = scale_tc.definition


def _certify_frf(results: RunResults, ch: str, c: RigConstants) -> None:
    """Gain (the generic fields, and ``gain_*``) and phase (``phase_*``) of every FRF point."""
    frf = results.analysis.frf
    for point in (frf.get(ch) or []) if frf else []:
        gain = _evaluated(frf_gain_measurand(point, results, c, ch), results)
        if gain is not None:
            certify(point, gain)
            point.gain_expanded_uncertainty_db = gain.expanded_uncertainty
            point.gain_budget = _rows(gain)
            point.gain_measurand = gain.definition
        phase = _evaluated(frf_phase_measurand(point, results, c, ch), results)
        if phase is not None:
            point.phase_expanded_uncertainty_deg = phase.expanded_uncertainty
            point.phase_budget = _rows(phase)
            point.phase_measurand = phase.definition
            point.phase_coverage_factor = phase.k  # the generic k is the gain's


def apply_uncertainty(results: RunResults, constants: RigConstants | None = None,
                      data: Any = None) -> RunResults:
    """Evaluate and write the uncertainty of every certified result (GUM, k = 2), in place.

    Writes the fields of :class:`aatest.results.base.Certified` (``expanded_uncertainty``,
    ``coverage_factor``, ``coverage_probability``, ``budget``) into ``analysis.scale_factor[CH]``,
    ``analysis.noise[CH]`` (the largest static record's band RMS),
    ``analysis.bias[CH]`` (bias; g-sensitivity as ``g_sensitivity_expanded_uncertainty_dps2_per_g``
    and ``g_sensitivity_budget``), ``analysis.temperature[CH]`` (bias coefficient; scale
    coefficient as ``scale_coefficient_*``), every point of ``analysis.frf[CH]`` (gain, plus
    ``gain_*``/``phase_*``), ``analysis.misalignment.scenarios[S][SENSOR]`` and the sensor's
    own axis tilt ``analysis.misalignment.matrix.scenarios[S][CH]``; and the
    reference's traceability the budgets rest on (``metadata.traceability``).

    Parameters
    ----------
    results
        The typed results of the analysis pass; changed in place and returned.
    constants
        The rig's stated accuracies (default: the run's rig description in its metadata,
        else the documented rig, docs/method.md §1.2, named as defaults in every basis).
    data
        The dataset the analyses ran on; the components the logs show (motion distortion,
        logged temperature) are measured from it (None: those rows say "not evaluated").
    """
    c = constants if constants is not None else RigConstants.from_results(results, data)
    results.metadata.traceability = ReferenceTraceability(
        stated=c.instruments_stated,
        instruments={k: InstrumentTrace(**v) for k, v in c.instruments.traceability().items()},
        reference_temperature_c=c.instruments.lab.reference_temperature_c,
    )
    for ch in channels(results):
        _certify_static(results, ch, c)
        _certify_frf(results, ch, c)
    block = results.analysis.misalignment
    for scenario, sensors in sorted(block.scenarios.items()) if block else []:
        for sensor, entry in sorted(sensors.items()):
            evaluation = _evaluated(misalignment_measurand(results, scenario, sensor, c), results)
            if evaluation is not None:
                certify(entry, evaluation)
    matrix = block.matrix if block else None
    for scenario, by_channel in sorted(matrix.scenarios.items()) if matrix else []:
        for channel, tilt in sorted(by_channel.items()):
            evaluation = _evaluated(sensor_tilt_measurand(results, scenario, channel, c), results)
            if evaluation is not None:
                certify(tilt, evaluation)
    return results
