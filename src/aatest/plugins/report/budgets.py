"""Evaluate every uncertainty the results support, keyed for the verdicts and the templates."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from aatest.plugins.report import extract as ex
from aatest.plugins.report.gum import Evaluation, evaluate
from aatest.plugins.report.uncertainty import (
    TEMPERATURE_COEFFICIENTS,
    RigConstants,
    bias_measurand,
    g_sensitivity_measurand,
    scale_factor_measurand,
    temperature_measurand,
)
from aatest.plugins.report.uncertainty_dynamic import (
    frf_gain_measurand,
    frf_phase_measurand,
    misalignment_measurand,
)


@dataclass
class FrfRow:
    """One FRF point with the expanded uncertainties of its gain and phase."""

    point: Mapping[str, Any]
    gain: Evaluation | None
    phase: Evaluation | None


@dataclass
class Budgets:
    """All evaluations: ``by_key["<quantity>/<channel>"]`` and FRF rows per channel."""

    by_key: dict[str, Evaluation] = field(default_factory=dict)
    frf: dict[str, list[FrfRow]] = field(default_factory=dict)

    def expanded(self) -> dict[str, float]:
        """``key → U`` for the verdict table."""
        return {k: e.expanded_uncertainty for k, e in self.by_key.items()}

    def shown(self) -> list[Evaluation]:
        """The budgets printed in full: every static quantity and, per channel, the FRF point
        with the largest gain uncertainty (the worst case of the table)."""
        rows = list(self.by_key.values())
        for channel_rows in self.frf.values():
            rated = [r for r in channel_rows if r.gain is not None]
            if rated:
                worst = max(rated, key=lambda r: r.gain.expanded_uncertainty if r.gain else 0.0)
                rows += [e for e in (worst.gain, worst.phase) if e is not None]
        return rows


def channels(results: Mapping[str, Any]) -> list[str]:
    """Sensor channels: metadata order first, then any channel only the analyses name."""
    names = list(ex.sensors(results))
    for key in ("scale_factor", "bias", "frf", "temperature", "transfer_function", "noise"):
        block = ex.analysis(results, key)
        if isinstance(block, Mapping):
            names += [str(ch) for ch in block if str(ch) not in names]
    return names


def _static(results: Mapping[str, Any], ch: str, c: RigConstants, out: Budgets) -> None:
    scale = scale_factor_measurand(results, ch, c)
    scale_rel: float | None = None
    if scale is not None:
        out.by_key[f"scale_factor/{ch}"] = ev = evaluate(scale)
        scale_rel = ev.standard_uncertainty / abs(ev.value) if ev.value else None
    measurands = [("bias", bias_measurand(results, ch, c)),
                  ("g_sensitivity", g_sensitivity_measurand(results, ch, c, scale_rel))]
    measurands += [(key, temperature_measurand(results, ch, key, c))
                   for key in TEMPERATURE_COEFFICIENTS]
    for key, measurand in measurands:
        if measurand is not None:
            out.by_key[f"{key}/{ch}"] = evaluate(measurand)


def _evaluate_or_none(measurand: Any) -> Evaluation | None:
    return evaluate(measurand) if measurand is not None else None


def evaluate_all(results: Mapping[str, Any], c: RigConstants) -> Budgets:
    """Every quantity the results contain, evaluated per GUM with k = 2."""
    out = Budgets()
    for ch in channels(results):
        _static(results, ch, c, out)
        points = (ex.analysis(results, "frf") or {}).get(ch) or []
        out.frf[ch] = [
            FrfRow(p, _evaluate_or_none(frf_gain_measurand(p, results, c)),
                   _evaluate_or_none(frf_phase_measurand(p, results, c)))
            for p in points if isinstance(p, Mapping)
        ]
    scenarios = (ex.analysis(results, "misalignment") or {}).get("scenarios") or {}
    for scenario, sensors in sorted(scenarios.items()):
        for sensor in sorted(sensors or {}):
            measurand = misalignment_measurand(results, str(scenario), str(sensor), c)
            if measurand is not None:
                out.by_key[f"misalignment/{scenario}/{sensor}"] = evaluate(measurand)
    return out
