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

Not measured is never passed (:mod:`.verdicts_missing`): a quantity the procedure asks for and
did not get, and a listed analysis that did not apply, are ``not judged`` with the reason; the
overall verdict is then ``incomplete`` (unless something failed) and the run exits 1.
``acceptance.judge`` chooses which quantities are judged. Whether the logger clipped (samples at
the rails of its stated input range, :mod:`.logger_rails`) is judged on every run that states
its logger, whatever ``judge`` lists: it says whether the other verdicts mean anything.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence

from aatest.engine.interfaces import SensorDatasheet
from aatest.engine.procedure.models import Acceptance
from aatest.metrology.logger_rails import QUANTITY as RAILS
from aatest.metrology.logger_rails import clipped_channels
from aatest.metrology.uncertainty.statistics import finite
from aatest.metrology.verdicts_limits import QUANTITY_UNITS
from aatest.metrology.verdicts_missing import Listed, limit_of, missing
from aatest.results import RunResults
from aatest.results.base import DecisionRule, Overall, Verdict, VerdictValue
from aatest.results.quantities import QUANTITIES
from aatest.results.scale_factor import ScaleFactorHeadline

#: unit of the logger-rail verdict's value and limit in results.json
RAILS_UNIT = QUANTITIES[RAILS].json_unit
#: verdicts from best to worst; the overall verdict is the worst one
SEVERITY: tuple[VerdictValue, ...] = ("pass", "conditional-pass", "conditional-fail", "fail")

#: table axis → the published method's label of the unit's sensor on it (docs/method.md §4.5)
AXIS_SENSOR = {"I": "SZ", "O": "SY", "P": "SX"}

#: (quantity, value, U or None) of one channel or sensor, before it is judged
Judged = tuple[str, float, float | None]


def decide(value: float, limit: float, u: float | None, rule: DecisionRule) -> VerdictValue:
    """One verdict under a decision rule (see the module docstring).

    ``value``, ``limit`` and ``u`` (the expanded uncertainty) share the judged quantity's unit
    (V, %, (°/s²)/g, … — or dimensionless for a ratio).

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
        if (nl := _nonlinearity(scale)) is not None:
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
    yield from _cross_axis(results, ch)


def _cross_axis(results: RunResults, ch: str) -> Iterator[Judged]:
    """A single-axis sensor's cross-axis ratio from outer-axis excitation, with its U."""
    block = results.analysis.cross_axis
    cross = block.get(ch) if block else None
    if cross is not None and (r := finite(cross.cross_axis_ratio)) is not None:
        yield "cross_axis_ratio", r, finite(cross.expanded_uncertainty)


def _nonlinearity(scale: ScaleFactorHeadline) -> float | None:
    """The linearity across the acceleration levels; None (``not judged``) with one level.

    One level resolves no non-linearity whatever order the fit chose: the polynomial's
    ``nonlinearity_pct_fr`` is its deviation from its own fit (1e-14 % FR, rounding), which
    would pass any limit by construction; the study's L of one level is reported, not judged.
    """
    if scale.linearity is not None:
        return finite(scale.linearity.nonlinearity_pct_fr)
    return None


def _levels(results: RunResults, ch: str, sheet: SensorDatasheet
            ) -> Iterator[tuple[str, Judged]]:
    """(label, scale-factor deviation) of every level but the headline, e.g. ``v_sz at
    100 °/s², 25 °C``."""
    block = results.analysis.scale_factor
    scale = block.get(ch) if block else None
    if scale is None:
        return
    for level in scale.levels:
        if (level.accel_dps2, level.temperature_c) == (scale.accel_dps2, scale.temperature_c):
            continue
        k, u_k = finite(level.scale_v_per_dps2), finite(level.expanded_uncertainty)
        if k is None:
            continue
        nominal = sheet.scale_v_per_dps2
        yield level_label(ch, level.accel_dps2, level.temperature_c), (
            "scale_factor_deviation_pct", 100.0 * (k / nominal - 1.0),
            None if u_k is None else 100.0 * u_k / nominal)


def _setpoints(results: RunResults, ch: str, sheet: SensorDatasheet
               ) -> Iterator[tuple[str, Judged]]:
    """(label, bias deviation) at every chamber set-point but the headline's."""
    block = results.analysis.bias
    bias = block.get(ch) if block else None
    if bias is None:
        return
    for point in bias.setpoints:
        if point.temperature_c == bias.temperature_c or (b := finite(point.bias_v)) is None:
            continue
        yield level_label(ch, None, point.temperature_c), (
            "bias_deviation_v", b - sheet.nominal_bias_v, finite(point.expanded_uncertainty))


def level_label(channel: str, accel_dps2: float | None, temperature_c: float | None) -> str:
    """How a verdict names one level: ``v_sz at 100 °/s²`` (``, -20 °C`` with a set-point)."""
    parts = [f"{accel_dps2:g} °/s²"] if accel_dps2 is not None else []
    parts += [f"{temperature_c:g} °C"] if temperature_c is not None else []
    return f"{channel} at {', '.join(parts)}" if parts else channel


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
        yield "noise_rms_v", worst, finite(noise.expanded_uncertainty)


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
          acceptance: Acceptance, listed: Sequence[Listed] = (),
          installed: Sequence[Listed] = ()) -> list[Verdict]:
    """Every judged quantity the results contain, in channel order, then the ones not judged.

    Parameters
    ----------
    results
        The typed results, after the uncertainty stage.
    sheets
        Each sensor channel's datasheet (:func:`aatest.engine.run.rig.datasheets`).
    acceptance
        The procedure's decision rule, limit overrides and ``judge`` list (defaults: simple,
        datasheet limits, every quantity asked).
    listed
        The analyses the procedure lists
        (:func:`aatest.engine.analysis.plugins.listed_analyses`).
    installed
        Every installed analysis (:func:`aatest.engine.analysis.plugins.installed_analyses`):
        a quantity nobody listed names the analysis that would produce it.
    """
    chosen = None if acceptance.judge is None else set(acceptance.judge)

    def verdict(channel: str, item: Judged, sheet: SensorDatasheet) -> Verdict:
        quantity, value, u = item
        limit, source = limit_of(quantity, sheet, acceptance)
        return Verdict(quantity=quantity, channel=channel, value=value, limit=limit,
                       expanded_uncertainty=u, rule=acceptance.rule,
                       verdict=decide(value, limit, u, acceptance.rule),
                       unit=QUANTITY_UNITS[quantity], limit_source=source)

    out = [verdict(ch, item, sheet) for ch, sheet in sheets.items()
           for item in _static(results, ch, sheet)]
    out += [verdict(label, item, sheet) for ch, sheet in sheets.items()
            for label, item in (*_levels(results, ch, sheet), *_setpoints(results, ch, sheet))]
    if sheets:
        out += [verdict(sensor, item, _sheet_of_sensor(sensor, sheets))
                for sensor, item in _misalignment(results)]
    out = [v for v in out if chosen is None or v.quantity in chosen]
    out += [Verdict(quantity=RAILS, channel=ch, value=float(n), limit=0.0, rule=acceptance.rule,
                    verdict=decide(n, 0.0, None, acceptance.rule), unit=RAILS_UNIT,
                    limit_source="logger")
            for ch, n in clipped_channels(results, sheets).items()]
    return out + missing(results, out, sheets, acceptance, listed, installed)


def overall(verdicts: Sequence[Verdict]) -> Overall:
    """The worst verdict; ``incomplete`` when something asked was not judged and nothing is
    worse than a conditional pass; ``none`` when nothing was judged or asked. A passed
    logger-rail verdict alone is no conformity with a specification: it leaves ``none``."""
    verdicts = [v for v in verdicts if not (v.quantity == RAILS and v.verdict == "pass")]
    judged = [v.verdict for v in verdicts if v.verdict != "not judged"]
    worst: Overall = max(judged, key=SEVERITY.index) if judged else "none"
    if len(judged) < len(verdicts) and worst in ("pass", "conditional-pass", "none"):
        return "incomplete"
    return worst


def apply_verdicts(results: RunResults, sheets: Mapping[str, SensorDatasheet],
                   acceptance: Acceptance, listed: Sequence[Listed] = (),
                   installed: Sequence[Listed] = ()) -> RunResults:
    """Judge the results and write ``verdicts`` and ``overall`` into them (in place)."""
    verdicts = judge(results, sheets, acceptance, listed, installed)
    results.verdicts = verdicts
    results.overall = overall(verdicts)
    return results


def failed(results: RunResults) -> bool:
    """True when the run must exit 1: a ``fail``, a ``conditional-fail`` under ``guarded``, or
    a quantity asked and ``not judged`` (the overall verdict ``incomplete``)."""
    return any(v.verdict in ("fail", "not judged")
               or (v.verdict == "conditional-fail" and v.rule == "guarded")
               for v in results.verdicts)
