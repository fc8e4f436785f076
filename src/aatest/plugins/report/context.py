"""The view model a template renders: plain mappings, dataclasses and vetted SVG only.

Templates hold no logic (docs/style.md): everything they show — sections that exist, values with
expanded uncertainties, verdicts, figures — is prepared here from ``results.json``, and a
section is present only when its analysis key is. Uncertainties, budgets and verdicts are the
engine's (:mod:`aatest.engine.uncertainty`, :mod:`aatest.engine.analysis.verdicts`): they are
shown as the results state them, never recomputed, and results without them are an error.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping
from datetime import UTC, datetime
from functools import partial
from pathlib import Path
from typing import Any

from aatest.engine.simulation import SIMULATION_TITLE, is_simulation
from aatest.engine.uncertainty import access as ex
from aatest.engine.uncertainty.budgets import channels
from aatest.plugins.report import figures as fig
from aatest.plugins.report.sandbox import vet_svg
from aatest.plugins.report.stated import budget_views, frf_rows, misalignment_rows, stated
from aatest.plugins.report.traceability import traceability

#: every section a report may show
ALL_SECTIONS = frozenset({"sync", "scale_factor", "bias", "temperature", "noise", "frf",
                          "transfer_function", "misalignment", "drift"})


def _coefficient_rows(entry: Mapping[str, Any]) -> list[dict[str, Any]]:
    rows = []
    ci95 = entry.get("ci95")
    for i, value in enumerate(entry.get("coefficients") or []):
        u = ex.ci_std(ci95, i)
        half = None if u is None else u * ex.Z95
        rows.append({"power": i, "value": value, "half_width": half})
    return rows


def _channel_view(results: Mapping[str, Any], ch: str) -> dict[str, Any]:
    def block(key: str) -> Any:
        value = (ex.analysis(results, key) or {})
        return value.get(ch) if isinstance(value, Mapping) else None

    scale = block("scale_factor")
    fit = scale.get("fit") if isinstance(scale, Mapping) else None
    r2 = (scale or {}).get("r2", (fit or {}).get("r2") if isinstance(fit, Mapping) else None)
    return {
        "r2": r2,
        "name": ch,
        "reference": (ex.require(scale, "reference", f"analysis.scale_factor.{ch}")
                      if isinstance(scale, Mapping) else None),
        "sensor": ex.sensors(results).get(ch, {}),
        "scale": scale,
        "coefficients": _coefficient_rows(scale) if isinstance(scale, Mapping) else [],
        "bias": block("bias"),
        "temperature": block("temperature"),
        "noise": block("noise"),
        "drift": block("drift"),
        "transfer_function": block("transfer_function"),
        "frf": frf_rows(results, ch),
        "u": stated(results, ch),
    }


def _analysis_figures(results: Mapping[str, Any], keys: Collection[str]) -> list[dict[str, Any]]:
    figures = results.get("figures") or {}
    out = []
    for key in sorted(figures):
        if key in keys and isinstance(figures[key], Mapping):
            out += [{"section": key, "title": f"{key}: {name}", "svg": vet_svg(svg)}
                    for name, svg in sorted(figures[key].items())]
    return out


def _own_figures(results: Mapping[str, Any], sections: Collection[str],
                 views: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Plots made here from the contract keys, for each section and channel the analysis
    plugins gave no figure of their own (a figure name containing the channel counts)."""
    stated = results.get("figures")
    given: Mapping[str, Any] = stated if isinstance(stated, Mapping) else {}

    def wanted(section: str, channel: str = "") -> bool:
        listed = given.get(section)
        names: Mapping[str, Any] = listed if isinstance(listed, Mapping) else {}
        return section in sections and not any(channel in str(name) for name in names)

    makers: list[tuple[str, str, Callable[[], str | None]]] = []
    peak = max(ex.step_values(ex.steps_of_kind(results, "sine"), "accel_dps2") or [0.0]) or None
    for v in views:
        if wanted("scale_factor", v["name"]) and isinstance(v["scale"], Mapping):
            makers.append(("scale_factor", f"calibration curve {v['name']}",
                           partial(fig.calibration_curve, v["scale"], v["sensor"], peak)))
        if wanted("frf", v["name"]) and v["frf"]:
            makers.append(("frf", f"Bode {v['name']}", partial(
                fig.bode, [r["point"] for r in v["frf"]], v["transfer_function"],
                [(r["gain"] or {}).get("expanded_uncertainty") or 0.0 for r in v["frf"]])))
        if wanted("temperature", v["name"]) and isinstance(v["temperature"], Mapping):
            makers.append(("temperature", f"bias vs temperature {v['name']}",
                           partial(fig.bias_vs_temperature, v["temperature"])))
    sets = (ex.analysis(results, "misalignment") or {}).get("sets")
    if wanted("misalignment") and isinstance(sets, Mapping):
        makers.append(("misalignment", "cross responses in the complex plane",
                       lambda: fig.misalignment_plane(sets)))
    out = []
    for section, title, make in makers:
        svg = make()
        if svg is not None:
            out.append({"section": section, "title": title, "svg": vet_svg(svg)})
    return out


def _rule(results: Mapping[str, Any]) -> str:
    """The decision rule the verdicts were made under (one per run)."""
    rules = sorted({str(v["rule"]) for v in ex.require(results, "verdicts", "top level")})
    return ", ".join(rules) or "no quantity judged"


def _header(results: Mapping[str, Any], run_dir: Path, kind: str, title: str) -> dict[str, Any]:
    """What every report shows at the top and bottom: title, signing key, traceability."""
    signature = results.get("signature")
    simulation = kind != "diagnosis" and is_simulation(results)  # never a calibration
    return {
        "report": {"kind": kind, "title": SIMULATION_TITLE if simulation else title,
                   "simulation": simulation,
                   "generated_utc": datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ")},
        "fingerprint": signature.get("fingerprint") if isinstance(signature, Mapping) else None,
        "certificate_number": results.get("certificate_number"),  # issued by aatest.records
        # the reference standards used and the non-conformities accepted (aatest.records)
        "reference_standards": (results.get("metadata") or {}).get("reference_standards") or [],
        "nonconformities": (results.get("metadata") or {}).get("nonconformities") or [],
        "trace": traceability(results, run_dir),
    }


def build_context(results: Mapping[str, Any], run_dir: Path, kind: str, title: str,
                  sections: Collection[str], plots: bool = True) -> dict[str, Any]:
    """Everything a measurement report template needs.

    Raises
    ------
    ResultsContractError
        When the results lack the engine's decisions (``verdicts``, ``overall``) or a
        contract key a section shows.
    """
    views = [_channel_view(results, ch) for ch in channels(results)]
    present = {s for s in sections if ex.analysis(results, s) is not None}
    return {
        **_header(results, run_dir, kind, title),
        "procedure": results.get("procedure"),
        "sections": sorted(present),
        "channels": views,
        "sync": ex.analysis(results, "sync") if "sync" in present else None,
        "misalignment": misalignment_rows(results) if "misalignment" in present else [],
        "misalignment_sets": ex.misalignment_sets(results),
        "verdicts": ex.require(results, "verdicts", "top level"),
        "overall": ex.require(results, "overall", "top level"),
        "rule": _rule(results),
        "budgets": budget_views(results, channels(results)),
        "figures": _analysis_figures(results, present)
        + (_own_figures(results, present, views) if plots else []),
        "steps": results.get("steps") or [],
        "analysis_errors": results.get("analysis_errors") or {},
        "analysis_skipped": results.get("analysis_skipped") or [],
    }


def _diagnosis_block(results: Mapping[str, Any]) -> Mapping[str, Any]:
    block = results.get("diagnosis")
    return block if isinstance(block, Mapping) else results


def _strongest_lines(lines: list[Any], count: int = 12) -> list[Mapping[str, Any]]:
    """The residual's strongest spectral lines, largest amplitude first."""
    rows = [x for x in lines if isinstance(x, Mapping)]
    return sorted(rows, key=lambda x: -(ex.as_float(x.get("amplitude_v")) or 0.0))[:count]


def build_diagnosis_context(results: Mapping[str, Any], run_dir: Path) -> dict[str, Any]:
    """View model of the ``aatest diagnose`` report (docs/interfaces.md §4)."""
    diag = _diagnosis_block(results)
    def rank(c: Mapping[str, Any]) -> tuple[bool, float]:
        bic = ex.as_float(c.get("delta_bic"))
        return bic is None, bic if bic is not None else 0.0  # untestable ones last

    candidates = sorted((c for c in diag.get("candidates") or [] if isinstance(c, Mapping)),
                        key=rank)
    figures = _analysis_figures(results, {"diagnose"})
    stated = diag.get("residuals")
    residuals: Mapping[str, Any] = stated if isinstance(stated, Mapping) else {}
    own = [("candidates and gain", fig.diagnosis_bars(diag))]
    own += [(f"residual RMS per step {ch}", fig.residual_steps(view))
            for ch, view in sorted(residuals.items()) if isinstance(view, Mapping)]
    figures += [{"section": "diagnose", "title": title, "svg": vet_svg(svg)}
                for title, svg in own if svg is not None]
    return {
        **_header(results, run_dir, "diagnosis", "Diagnosis: what the simulation gets wrong"),
        "baseline": diag.get("baseline") or {},
        "findings": [f for f in diag.get("findings") or [] if isinstance(f, Mapping)],
        "candidates": candidates,
        "gain": diag.get("gain") or {},
        "residuals": {ch: {"per_step": list(v.get("per_step") or []),
                           "lines": _strongest_lines(v.get("spectrum_lines") or [])}
                      for ch, v in sorted(residuals.items()) if isinstance(v, Mapping)},
        "figures": figures,
    }
