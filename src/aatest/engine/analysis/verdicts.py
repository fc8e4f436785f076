"""The verdict stage: every certified quantity judged against its acceptance limit (ILAC-G8).

Runs after the uncertainty stage (it reads the expanded uncertainties written there) and writes
``results.verdicts`` (:class:`aatest.results.base.Verdict`) and ``results.overall``.
Reports only render these; ``aatest run``/``analyze`` exit 1 when :func:`failed` says so.

Decision rules (ILAC-G8:2019, JCGM 106:2012), U the value's expanded uncertainty:

- ``simple``: pass iff |value| ≤ limit.
- ``guarded`` (guard band = U): pass iff |value| + U ≤ limit, fail iff |value| − U > limit,
  otherwise ``conditional-pass`` (|value| ≤ limit) or ``conditional-fail``.
- ``shared-risk``: as simple, but a verdict whose |value| lies within U of the limit is
  ``conditional-pass``/``conditional-fail`` (the risk is shared and stated).

A quantity without an evaluated U is judged with U = 0 (no guard band, nothing conditional).
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence

from aatest.engine.analysis.verdicts_limits import QUANTITY_UNITS, limits
from aatest.engine.interfaces import SensorDatasheet
from aatest.engine.procedure.models import Acceptance
from aatest.engine.uncertainty.statistics import finite
from aatest.results import RunResults
from aatest.results.base import DecisionRule, Overall, Verdict, VerdictValue

#: verdicts from best to worst; the overall verdict is the worst one
SEVERITY: tuple[VerdictValue, ...] = ("pass", "conditional-pass", "conditional-fail", "fail")

#: table axis → the published method's label of the unit's sensor on it (docs/method.md §4.5)
AXIS_SENSOR = {"I": "SZ", "O": "SY", "P": "SX"}

#: (quantity, value, U or None) of one channel or sensor, before it is judged
Judged = tuple[str, float, float | None]


def decide(value: float, limit: float, u: float | None, rule: DecisionRule) -> VerdictValue:
    """One verdict under a decision rule (see the module docstring).

    >>> decide(0.9, 1.0, 0.2, "simple"), decide(0.9, 1.0, 0.2, "guarded")
    ('pass', 'conditional-pass')
    >>> decide(1.05, 1.0, 0.2, "shared-risk"), decide(1.5, 1.0, 0.2, "guarded")
    ('conditional-fail', 'fail')
    """
    size, band = abs(value), u or 0.0
    within = size <= limit
    if rule == "guarded":
        if size + band <= limit:
            return "pass"
        if size - band > limit:
            return "fail"
    elif rule == "simple" or abs(size - limit) >= band:
        return "pass" if within else "fail"
    return "conditional-pass" if within else "conditional-fail"


def _static(results: RunResults, ch: str, sheet: SensorDatasheet) -> Iterator[Judged]:
    """Scale factor, non-linearity, bias, g-sensitivity and temperature coefficients."""
    a = results.analysis
    scale = a.scale_factor.get(ch) if a.scale_factor else None
    if scale is not None:
        k, u_k = finite(scale.scale_v_per_dps2), finite(scale.expanded_uncertainty)
        nominal = sheet.scale_v_per_dps2
        if k is not None:
            yield ("scale_factor_deviation_pct", 100.0 * (k / nominal - 1.0),
                   None if u_k is None else 100.0 * u_k / nominal)
        if (nl := finite(scale.nonlinearity_pct_fr)) is not None:
            yield "nonlinearity_pct_fr", nl, None
    bias = a.bias.get(ch) if a.bias else None
    if bias is not None:
        if (b := finite(bias.bias_v)) is not None:
            yield "bias_deviation_v", b - sheet.nominal_bias_v, finite(bias.expanded_uncertainty)
        if (g := finite(bias.g_sensitivity_dps2_per_g)) is not None:
            yield ("g_sensitivity_dps2_per_g", g,
                   finite(bias.g_sensitivity_expanded_uncertainty_dps2_per_g))
    yield from _thermal(results, ch)
    yield from _noise(results, ch)


def _thermal(results: RunResults, ch: str) -> Iterator[Judged]:
    block = results.analysis.temperature
    temperature = block.get(ch) if block else None
    if temperature is None:
        return
    if (c := finite(temperature.bias_coefficient_v_per_c)) is not None:
        yield "bias_temperature_v_per_c", c, finite(temperature.expanded_uncertainty)
    if (c := finite(temperature.scale_coefficient_per_c)) is not None:
        yield ("scale_temperature_per_c", c,
               finite(temperature.scale_coefficient_expanded_uncertainty_per_c))


def _noise(results: RunResults, ch: str) -> Iterator[Judged]:
    """Output noise: the worst step decides (the noise analysis' ``rms_max_v``)."""
    block = results.analysis.noise
    noise = block.get(ch) if block else None
    if noise is not None and (worst := finite(noise.rms_max_v)) is not None:
        yield "noise_rms_v", worst, None


def _misalignment(results: RunResults) -> Iterator[tuple[str, Judged]]:
    """(sensor label, judged): the sensor's own cross-axis sensitivity and axis misalignment.

    Judged per scenario on the pivot-separated sensor part of the sensitivity-matrix estimate
    (``matrix.scenarios``): half the difference of the original and pivoted mountings' direction
    ratios, which flips with the pivot and so belongs to the sensor, while the mounting block's
    and seat's tilts (which do not flip) cancel. Internal misalignment and cross-axis sensitivity
    tilt the effective input axis alike and this test cannot tell them apart, so one estimate
    gives both: the cross-axis ratio tan θ and the input-axis misalignment θ, each with the
    expanded uncertainty of θ. The per-set ratios |A_x|/|A_z| and the published δ carry the
    mounting's tilt too: they stay in the results as information about the fixture, not judged.
    """
    block = results.analysis.misalignment
    matrix = block.matrix if block is not None else None
    if matrix is None:
        return
    for scenario, by_channel in sorted(matrix.scenarios.items()):
        for channel, tilt in sorted(by_channel.items()):
            angle = finite(tilt.sensor_angle_deg)
            if angle is None:
                continue
            u_deg = finite(tilt.expanded_uncertainty)
            rad = math.radians(angle)
            u_ratio = None if u_deg is None else math.radians(u_deg) / math.cos(rad) ** 2
            label = f"{_sensor_label(matrix.rows, matrix.columns, channel)} scenario {scenario}"
            yield label, ("cross_axis_ratio", math.tan(rad), u_ratio)
            yield label, ("misalignment_deg", angle, u_deg)


def _sensor_label(rows: Sequence[str], columns: Sequence[str], channel: str) -> str:
    """A unit channel (``v_sx``) → the published method's sensor label (``SX``).

    The matrix's rows are the unit's channels in the order of its columns (table axes P, O, I):
    row i is the sensor on axis ``columns[i]``.
    """
    if channel in rows and rows.index(channel) < len(columns):
        return AXIS_SENSOR.get(columns[rows.index(channel)], channel)
    return channel


def _sheet_of_sensor(sensor: str, sheets: Mapping[str, SensorDatasheet]) -> SensorDatasheet:
    """A misalignment sensor label (``SZ scenario 1``) → its channel's (``v_sz``) datasheet."""
    channel = f"v_{sensor.split(maxsplit=1)[0].lower()}"
    return sheets.get(channel) or next(iter(sheets.values()))


def judge(results: RunResults, sheets: Mapping[str, SensorDatasheet],
          acceptance: Acceptance) -> list[Verdict]:
    """Every judged quantity the results contain, in channel order.

    Parameters
    ----------
    results
        The typed results, after the uncertainty stage.
    sheets
        Each sensor channel's datasheet (:func:`~.verdicts_limits.datasheets`).
    acceptance
        The procedure's decision rule and limit overrides (defaults: simple, datasheet).
    """
    def verdict(channel: str, item: Judged, sheet: SensorDatasheet) -> Verdict:
        quantity, value, u = item
        limit = limits(sheet, acceptance)[quantity]
        return Verdict(quantity=quantity, channel=channel, value=value, limit=limit,
                       expanded_uncertainty=u, rule=acceptance.rule,
                       verdict=decide(value, limit, u, acceptance.rule),
                       unit=QUANTITY_UNITS[quantity])

    out = [verdict(ch, item, sheet) for ch, sheet in sheets.items()
           for item in _static(results, ch, sheet)]
    if sheets:
        out += [verdict(sensor, item, _sheet_of_sensor(sensor, sheets))
                for sensor, item in _misalignment(results)]
    return out


def overall(verdicts: Sequence[Verdict]) -> Overall:
    """The worst verdict, ``none`` when nothing was judged."""
    if not verdicts:
        return "none"
    return max((v.verdict for v in verdicts), key=SEVERITY.index)


def apply_verdicts(results: RunResults, sheets: Mapping[str, SensorDatasheet],
                   acceptance: Acceptance) -> RunResults:
    """Judge the results and write ``verdicts`` and ``overall`` into them (in place)."""
    verdicts = judge(results, sheets, acceptance)
    results.verdicts = verdicts
    results.overall = overall(verdicts)
    return results


def failed(results: RunResults) -> bool:
    """True when the run must exit 1: a ``fail``, or a ``conditional-fail`` under ``guarded``."""
    return any(v.verdict == "fail" or (v.verdict == "conditional-fail" and v.rule == "guarded")
               for v in results.verdicts)
