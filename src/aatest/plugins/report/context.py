"""The view model a template renders: plain mappings, dataclasses and vetted SVG only.

Templates hold no logic: everything they show — sections that exist, values with expanded
uncertainties, verdicts, figures — is prepared here from the typed record
(:class:`aatest.results.RunResults`), and a section is present only when its analysis is.
Uncertainties, budgets and verdicts are the engine's (:mod:`aatest.metrology.uncertainty`,
:mod:`aatest.metrology.verdicts`): shown as the results state them, never recomputed.
Quantities are shown by their names and unit symbols (:mod:`aatest.results.quantities`).
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping
from datetime import UTC, datetime
from functools import partial
from pathlib import Path
from typing import Any

from aatest.engine.simulation import SIMULATION_TITLE, is_simulation
from aatest.metrology.uncertainty.budgets import channels
from aatest.plugins.report import figures as fig
from aatest.plugins.report.sandbox import vet_svg
from aatest.plugins.report.stated import budget_views, frf_rows, misalignment_rows, stated
from aatest.plugins.report.traceability import traceability
from aatest.results import RunResults, Verdict
from aatest.results.quantities import analysis_name, finite, quantity, reference_name
from aatest.results.scale_factor import ScaleFactorChannel

#: every section a report may show
ALL_SECTIONS = frozenset({"sync", "scale_factor", "bias", "temperature", "noise", "frf",
                          "transfer_function", "misalignment", "drift"})


def _coefficient_rows(entry: ScaleFactorChannel) -> list[dict[str, Any]]:
    rows = []
    for i, value in enumerate(entry.coefficients):
        ci = entry.ci95[i] if i < len(entry.ci95) else []
        lo, hi = (finite(ci[0]), finite(ci[1])) if len(ci) == 2 else (None, None)  # noqa: PLR2004
        half = abs(hi - lo) / 2 if lo is not None and hi is not None else None
        rows.append({"power": i, "value": value, "half_width": half})
    return rows


def _channel_view(results: RunResults, ch: str) -> dict[str, Any]:
    a = results.analysis
    scale = a.scale_factor.get(ch) if a.scale_factor else None
    return {
        "r2": scale.fit.r2 if scale is not None else None,
        "name": ch,
        "reference": reference_name(scale.reference) if scale else None,
        "sensor": results.sensor(ch),
        "scale": scale,
        "coefficients": _coefficient_rows(scale) if scale is not None else [],
        "bias": a.bias.get(ch) if a.bias else None,
        "temperature": a.temperature.get(ch) if a.temperature else None,
        "noise": a.noise.get(ch) if a.noise else None,
        "drift": a.drift.get(ch) if a.drift else None,
        "transfer_function": a.transfer_function.get(ch) if a.transfer_function else None,
        "frf": frf_rows(results, ch),
        "u": stated(results, ch),
    }


def _figure_title(section: str, name: str) -> str:
    """``Scale factor: v_sz`` for the figure ``scale_factor_v_sz`` of the scale-factor analysis."""
    what = name.removeprefix(section).strip("_") or analysis_name(section).lower()
    return f"{analysis_name(section)}: {what.replace('_', ' ')}"


def _analysis_figures(results: RunResults, keys: Collection[str]) -> list[dict[str, Any]]:
    out = []
    for key in sorted(results.figures):
        if key in keys:
            out += [{"section": key, "title": _figure_title(key, name), "svg": vet_svg(svg)}
                    for name, svg in sorted(results.figures[key].items())]
    return out


def _own_figures(results: RunResults, sections: Collection[str],
                 views: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Plots made here from the typed results, for each section and channel the analysis
    plugins gave no figure of their own (a figure name containing the channel counts)."""
    def wanted(section: str, channel: str = "") -> bool:
        names = results.figures.get(section, {})
        return section in sections and not any(channel in name for name in names)

    makers: list[tuple[str, str, Callable[[], str | None]]] = []
    accels = [s.accel_dps2 for s in results.steps_of_kind("sine") if finite(s.accel_dps2)]
    peak = max([a for a in accels if a is not None] or [0.0]) or None
    for v in views:
        if wanted("scale_factor", v["name"]) and v["scale"] is not None:
            makers.append(("scale_factor", f"calibration curve {v['name']}",
                           partial(fig.calibration_curve, v["scale"], v["sensor"], peak)))
        if wanted("frf", v["name"]) and v["frf"]:
            makers.append(("frf", f"Bode {v['name']}", partial(
                fig.bode, [r["point"] for r in v["frf"]], v["transfer_function"],
                [(r["gain"].expanded_uncertainty if r["gain"] else None) or 0.0
                 for r in v["frf"]])))
        if wanted("temperature", v["name"]) and v["temperature"] is not None:
            makers.append(("temperature", f"bias vs temperature {v['name']}",
                           partial(fig.bias_vs_temperature, v["temperature"])))
    block = results.analysis.misalignment
    if wanted("misalignment") and block is not None and block.sets:
        makers.append(("misalignment", "cross responses in the complex plane",
                       lambda: fig.misalignment_plane(block.sets)))
    out = []
    for section, title, make in makers:
        svg = make()
        if svg is not None:
            out.append({"section": section, "title": title, "svg": vet_svg(svg)})
    return out


def _rule(results: RunResults) -> str:
    """The decision rule the verdicts were made under (one per run)."""
    return ", ".join(sorted({v.rule for v in results.verdicts})) or "no quantity judged"


def verdict_rows(verdicts: list[Verdict]) -> list[dict[str, Any]]:
    """The engine's verdicts as a person reads them: the quantity's name and unit symbol, the
    value, limit and U with its significant digits."""
    rows = []
    for v in verdicts:
        q = quantity(v.quantity)
        rows.append({"quantity": q.name, "key": v.quantity, "channel": v.channel,
                     "value": v.value, "limit": v.limit, "digits": q.digits,
                     "expanded_uncertainty": v.expanded_uncertainty,
                     "unit": q.unit or "—", "rule": v.rule, "verdict": v.verdict,
                     "limit_source": v.limit_source or "", "reason": v.reason})
    return rows


def _header(results: RunResults, run_dir: Path, kind: str, title: str) -> dict[str, Any]:
    """What every report shows at the top and bottom: title, signing key, traceability."""
    simulation = kind != "diagnosis" and is_simulation(results)  # never a calibration
    return {
        "report": {"kind": kind, "title": SIMULATION_TITLE if simulation else title,
                   "simulation": simulation,
                   "generated_utc": datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ")},
        "fingerprint": results.signature.fingerprint if results.signature else None,
        "certificate_number": results.certificate_number,  # issued by aatest.records
        # the reference standards used and the non-conformities accepted (aatest.records)
        "reference_standards": results.metadata.recorded("reference_standards") or [],
        "nonconformities": results.metadata.recorded("nonconformities") or [],
        "trace": traceability(results, run_dir),
    }


def build_context(results: RunResults, run_dir: Path, kind: str, title: str,
                  sections: Collection[str], plots: bool = True) -> dict[str, Any]:
    """Everything a measurement report template needs, from the typed record."""
    names = channels(results)
    views = [_channel_view(results, ch) for ch in names]
    present = {s for s in sections if s in results.analysis.present()}
    block = results.analysis.misalignment
    return {
        **_header(results, run_dir, kind, title),
        "procedure": results.procedure,
        "sections": sorted(present),
        "channels": views,
        "sync": results.analysis.sync if "sync" in present else None,
        "misalignment": misalignment_rows(results) if "misalignment" in present else [],
        "misalignment_sets": block.sets if block else {},
        "verdicts": verdict_rows(results.verdicts),
        "overall": results.overall,
        "rule": _rule(results),
        "budgets": budget_views(results, names),
        "figures": _analysis_figures(results, present)
        + (_own_figures(results, present, views) if plots else []),
        "steps": results.steps,
        "analysis_errors": {analysis_name(k): m for k, m in results.analysis_errors.items()},
        "analysis_skipped": [analysis_name(k) for k in results.analysis_skipped],
    }


def _unrecorded(document: Mapping[str, Any]) -> RunResults:
    """A diagnosis has no run results: the header states what it names, the rest as not
    recorded."""
    named = document.get("procedure")
    return RunResults(procedure=named if isinstance(named, str) else "—")


def _number(value: Any) -> float | None:
    """A finite float from a diagnosis document's value, else None."""
    return finite(float(value)) if isinstance(value, int | float) else None


def _diagnosis_block(document: Mapping[str, Any]) -> Mapping[str, Any]:
    block = document.get("diagnosis")
    return block if isinstance(block, Mapping) else document


def _strongest_lines(lines: list[Any], count: int = 12) -> list[Mapping[str, Any]]:
    """The residual's strongest spectral lines, largest amplitude first."""
    rows = [x for x in lines if isinstance(x, Mapping)]
    return sorted(rows, key=lambda x: -(_number(x.get("amplitude_v")) or 0.0))[:count]


def _unexplained_rows(diag: Mapping[str, Any]) -> list[dict[str, Any]]:
    """``unexplained`` entries with their scalar extension parameters and their gain (%)."""
    rows = []
    for u in diag.get("unexplained") or []:
        if not isinstance(u, Mapping):
            continue
        stated_ext, stated_ev = u.get("extension"), u.get("evidence")
        ext: Mapping[str, Any] = stated_ext if isinstance(stated_ext, Mapping) else {}
        ev: Mapping[str, Any] = stated_ev if isinstance(stated_ev, Mapping) else {}
        params = [(str(k), v) for k, v in ext.items()
                  if isinstance(v, (int, float, str)) and not isinstance(v, bool)]
        before, after = _number(ev.get("rmse_v_before")), _number(ev.get("rmse_v_after"))
        gain = 100.0 * (1.0 - after / before) if before and after is not None else None
        rows.append({**u, "evidence": ev, "parameters": params, "gain_pct": gain})
    return rows


def build_diagnosis_context(document: Mapping[str, Any], run_dir: Path) -> dict[str, Any]:
    """View model of the ``aatest diagnose`` report (docs/interfaces.md §4)."""
    diag = _diagnosis_block(document)
    def rank(c: Mapping[str, Any]) -> tuple[bool, float]:
        bic = _number(c.get("delta_bic"))
        return bic is None, bic if bic is not None else 0.0  # untestable ones last

    candidates = sorted((c for c in diag.get("candidates") or [] if isinstance(c, Mapping)),
                        key=rank)
    given = document.get("figures")
    drawn = given.get("diagnose") if isinstance(given, Mapping) else None
    figures = [{"section": "diagnose", "title": f"Diagnosis: {name.replace('_', ' ')}",
                "svg": vet_svg(svg)}
               for name, svg in sorted((drawn or {}).items()) if isinstance(svg, str)]
    stated = diag.get("residuals")
    residuals: Mapping[str, Any] = stated if isinstance(stated, Mapping) else {}
    own = [("candidates and gain", fig.diagnosis_bars(diag))]
    own += [(f"residual RMS per step {ch}", fig.residual_steps(view))
            for ch, view in sorted(residuals.items()) if isinstance(view, Mapping)]
    figures += [{"section": "diagnose", "title": title, "svg": vet_svg(svg)}
                for title, svg in own if svg is not None]
    return {
        **_header(_unrecorded(document), run_dir, "diagnosis",
                  "Diagnosis: what the simulation gets wrong"),
        "baseline": diag.get("baseline") or {},
        "findings": [f for f in diag.get("findings") or [] if isinstance(f, Mapping)],
        "candidates": candidates,
        "gain": diag.get("gain") or {},
        "gain_named": diag.get("gain_named") or {},
        "unexplained": _unexplained_rows(diag),
        "verdict": diag.get("verdict") or {},
        "noise_floor": diag.get("noise_floor") or {},
        "residuals": {ch: {"per_step": list(v.get("per_step") or []),
                           "lines": _strongest_lines(v.get("spectrum_lines") or [])}
                      for ch, v in sorted(residuals.items()) if isinstance(v, Mapping)},
        "figures": figures,
        "steps_clipped": [(str(step), sorted((str(ch), n) for ch, n in at.items()))
                          for step, at in (diag.get("steps_clipped") or {}).items()
                          if isinstance(at, Mapping)],
        "steps_skipped": [str(step) for step in diag.get("steps_skipped") or []],
    }
