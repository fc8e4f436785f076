"""The diagnose pipeline on a Dataset: replay, residuals, candidates, selection, gain.

Returns the contract document (docs/interfaces.md §4) plus extra keys: per-channel calibration,
residual views, the logger chain assumed, and the not-testable reasons.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from aatest.diagnose.alignment import nominal_fit
from aatest.diagnose.candidates.base import Context, replace_spec
from aatest.diagnose.candidates.logger import (
    DEFAULT_CLOCK_TOLERANCE_PPM,
    clock_drift,
    excess_noise,
    one_clock_fit,
    phase_trend_drift,
)
from aatest.diagnose.design import predict
from aatest.diagnose.figures import residual_figures
from aatest.diagnose.gram import Fit
from aatest.diagnose.logger_chain import (
    channel_info,
    logger_options,
    stated_converter,
    targets_of,
)
from aatest.diagnose.noise_floor import EXPLAINED_RATIO, METHOD, NoiseFloor, noise_floor
from aatest.diagnose.replay import Replay, replay_dataset
from aatest.diagnose.residuals import residual_views
from aatest.diagnose.selection import (
    BIC_THRESHOLD,
    ChannelResult,
    Finding,
    correlation_factor,
    explain_refusals,
    forward_select,
    rmse,
)
from aatest.diagnose.story import residual_entry, verdict
from aatest.diagnose.unexplained import Outcome, explain, held_out_rmse, joint_residuals
from aatest.numerics import TINY, Z95
from aatest.recording.dataset import Dataset


def diagnose_channel(dataset: Dataset, replay: Replay, channel: str,
                     corner: float | None) -> tuple[ChannelResult, Context]:
    """Nominal fit, noise correlation and forward selection for one channel."""
    ctx = Context(replay, channel_info(dataset, channel, corner, replay.t_ref_c),
                  targets_of(replay, channel), None,  # type: ignore[arg-type]
                  converter_step_v=stated_converter(dataset)[0].step_v)
    nominal = nominal_fit(ctx)
    ctx.current = nominal
    ctx.correlation = correlation_factor(ctx, nominal)
    findings, rows = forward_select(ctx)
    return ChannelResult(channel, nominal, ctx.current, findings, rows, ctx.correlation), ctx


@dataclass(frozen=True)
class _Drift:
    """A drift estimate, where it came from, and how the replay must be warped for it."""

    drift_ppm: float
    ci: list[float]
    source: str
    before: Fit
    after: Fit
    baseline_warp_ppm: float | None = None
    final_warp: tuple[float, bool] | None = None


def _edge_resolution_ppm(ctx: Context) -> float:
    """Drift the edges cannot see without latch times: one sample over the longest record."""
    longest = max(s.time_s[-1] for s in ctx.replay.steps)
    return ctx.replay.dt_s / max(longest, 1e-9) * 1e6


def _estimate_drift(ctx: Context) -> _Drift | None:
    """Edges when present (refined by the phase trend when they resolve one sample only),
    else the phase trend alone."""
    est = clock_drift(ctx)
    if est is None:
        trend = phase_trend_drift(ctx, from_start=True)
        if trend is None:
            return None
        d, ci, fit = trend
        return _Drift(d, ci, "phase trend (no sync edges)", ctx.current, fit, None, (-d, True))
    d, u = est.drift_ppm, est.u_ppm
    bound = est.range_ppm  # without latch times: the drifts the edges allow, a hard bound
    ci = [d - Z95 * u, d + Z95 * u] if bound is None else [bound[0], bound[1]]
    edges = _Drift(d, ci, "sync edges", one_clock_fit(ctx, d), ctx.current, d, None)
    if ctx.replay.fp_latch:
        return edges
    res = _edge_resolution_ppm(ctx)
    trend = phase_trend_drift(ctx, from_start=False, limit_ppm=3.0 * res,
                              bounds_ppm=None if bound is None else (bound[0] - d, bound[1] - d))
    if trend is None or (trend[1][1] - trend[1][0]) / 2 > res:
        return edges
    extra, ci, fit = trend
    lo, hi = (d + ci[0], d + ci[1]) if bound is None else (max(d + ci[0], bound[0]),
                                                          min(d + ci[1], bound[1]))
    return _Drift(d + extra, [lo, hi], "sync edges (one-sample resolution) + phase trend",
                  one_clock_fit(ctx, d), fit, d, (-extra, False))


def _drift_finding(ctx: Context, tolerance_ppm: float) -> tuple[Finding | None, dict[str, Any]]:
    """Clock drift from the sync edges and/or the phase trend, a finding beyond tolerance."""
    row: dict[str, Any] = {"effect": "clock_drift", "accepted": False, "testable": True,
                           "attributed_to": "logger", "tolerance_ppm": tolerance_ppm}
    est = _estimate_drift(ctx)
    if est is None:
        return None, {**row, "delta_bic": None, "testable": False,
                      "reason": "no sync edges and no sine step to show a phase trend"}
    n_eff = est.before.n / ctx.correlation
    dbic = float(n_eff * np.log(max(est.after.sse_held_out, TINY)
                                / max(est.before.sse_held_out, TINY)) + np.log(n_eff))
    row |= {"delta_bic": dbic, "parameters": {"drift_ppm": est.drift_ppm}, "source": est.source}
    significant = est.ci[0] > 0 or est.ci[1] < 0
    measured_by_edges = est.source == "sync edges"
    if abs(est.drift_ppm) <= tolerance_ppm or not significant or (
            dbic > -BIC_THRESHOLD and not measured_by_edges):
        row["reason"] = f"|drift| within the rig's clock tolerance ({tolerance_ppm:g} ppm)"
        return None, row
    row["accepted"] = True
    return Finding("clock_drift", "all", {"drift_ppm": est.drift_ppm}, {"drift_ppm": est.ci},
                   dbic, rmse(est.before), rmse(est.after), "logger", {"source": est.source},
                   est.baseline_warp_ppm, est.final_warp), row


def _with_drift(ctx: Context, result: ChannelResult, drift: Finding | None) -> tuple[Fit, Fit]:
    """(baseline, final) fits with the clock drift taken into account.

    Nominal means one clock (docs/interfaces.md §4 step 1): data the edges drift-corrected get a
    one-clock baseline warped by that correction; drift seen in the phase trend is carried by
    the extended model's warp.
    """
    if drift is None:
        return result.nominal, result.final
    baseline_warp, final_warp = drift.baseline_warp_ppm, drift.final_warp
    baseline, final = result.nominal, result.final
    if baseline_warp is not None:
        baseline = ctx.fit(replace_spec(result.nominal.spec, warp_ppm=baseline_warp))
    if final_warp is not None:
        w, from_start = final_warp
        spec = replace_spec(result.final.spec, warp_ppm=w, warp_from_start=from_start)
        if from_start:
            spec = replace_spec(spec, delay_s=0.0, step_shift_s=())
        final = ctx.fit(spec)
    return baseline, final


def _noise_finding(ctx: Context, stated_noise_v: float) -> tuple[Finding | None, dict[str, Any]]:
    """Excess white noise, read on the steps at rest when there are any.

    Excess noise (cabling, a slip ring) is added whatever the table does, so at rest — where
    the output holds no motion at all — it is all that stands above the pre-sample filter
    band. A floor seen only while the table moves is motion the model reproduces imperfectly
    (a large ripple's jerk, a high harmonic), not noise.
    """
    pred = predict(ctx.replay, ctx.info, ctx.current)
    still = {s.index for s in ctx.replay.steps if not (s.inner.moving or s.outer.moving)}
    residuals = {i: ctx.targets[i] - pred[i] for i in pred if not still or i in still}
    value, ci, veto, dbic = excess_noise(ctx, residuals, stated_noise_v)
    total = rmse(ctx.current)
    share = min(value**2 / total**2, 1.0) if total > 0 else 0.0
    row = {"effect": "excess_noise", "delta_bic": dbic, "accepted": veto is None, "testable": True,
           "parameters": {"rms_v": value}, "channel": ctx.info.channel, "attributed_to": "logger"}
    if veto is not None:
        row["reason"] = veto
        return None, row
    return Finding("excess_noise", ctx.info.channel, {"rms_v": value}, {"rms_v": ci}, dbic,
                   total, total, "logger",
                   {"explained_variance_pct": 100.0 * share}), row


def _calibration(result: ChannelResult, ctx: Context) -> dict[str, Any]:
    fit = result.final
    return {"channel": result.channel, "axis": ctx.info.axis, "bias_v": fit.value("bias"),
            "scale_v_per_dps2": ctx.scale_of(fit), "range_dps2": ctx.info.range_dps2,
            "noise_rms_v": rmse(fit), "noise_correlation": result.correlation,
            "alignment_offsets_s": [result.nominal.spec.shift_of(s.index)
                                    for s in ctx.replay.steps]}


# the design products are thin (tens of columns): threaded BLAS gains nothing on them and, on
# a busy machine, each call waits for its threads to wake (measured 500× slower per dot)
@threadpool_limits.wrap(limits=1, user_api="blas")
def diagnose_dataset(dataset: Dataset, clock_tolerance_ppm: float | None = None,
                     figures: dict[str, str] | None = None) -> dict[str, Any]:
    """Run the whole pipeline; return the diagnosis document (contract keys plus extras).

    ``figures``, when given, receives the residual-view SVGs of the report (title → SVG).
    """
    replay = replay_dataset(dataset)
    tol = clock_tolerance_ppm or float(dataset.metadata.get("clock_tolerance_ppm")
                                       or DEFAULT_CLOCK_TOLERANCE_PPM)
    options = logger_options(dataset, replay)
    docs: list[tuple[dict[str, Any], dict[str, str]]] = []
    for corner, reason in options:  # ambiguous chain: the one needing fewer effects wins
        figs: dict[str, str] = {}
        docs.append((_diagnose_with(dataset, replay, corner, reason, tol,
                                    figs if figures is not None else None), figs))
        if not docs[-1][0]["findings"]:
            break  # nothing to explain: no other chain can be simpler
    doc, figs = min(docs, key=lambda d: (len(d[0]["findings"]), d[0]["gain"]["rmse_v_after"]))
    if figures is not None:
        figures.update(figs)
    return doc


def _diagnose_with(dataset: Dataset, replay: Replay, corner: float | None, source: str,
                   tol: float, figures: dict[str, str] | None = None) -> dict[str, Any]:
    """The diagnosis document for one assumed logger chain (``figures`` filled when given)."""
    findings: list[Finding] = []
    candidates: list[dict[str, Any]] = []
    unexplained: list[dict[str, Any]] = []
    channels, views = [], {}
    floors: dict[str, dict[str, Any]] = {}
    sse = np.zeros(3)  # held-out SSE: baseline, named model, named + generic extensions
    n_total = 0
    drift_f: Finding | None = None
    for i, channel in enumerate(replay.channels):
        result, ctx = diagnose_channel(dataset, replay, channel, corner)
        noise_f, noise_row = _noise_finding(ctx, dataset.sensor(channel).noise_rms_v)
        if i == 0:
            drift_f, drift_row = _drift_finding(ctx, tol)
            candidates.append(drift_row)
            findings += [drift_f] if drift_f else []
        baseline, result.final = _with_drift(ctx, result, drift_f)
        outcome = explain(ctx, result.final, result.findings)
        _apply_withdrawals(result, outcome)
        findings += result.findings + ([noise_f] if noise_f else [])
        candidates += [*list(result.candidates.values()), noise_row]
        result.final = ctx.fit(outcome.joint.spec)
        sse += [baseline.sse_held_out, result.final.sse_held_out, outcome.joint.fit.sse_held_out]
        n_total += result.final.n
        channels.append(_calibration(result, ctx))
        floors[channel], rest, views[channel] = _residual_story(ctx, result.nominal, baseline,
                                                                outcome, figures)
        unexplained += outcome.unexplained + rest
    findings = sorted(_dedupe_table_effects(findings), key=lambda f: f.delta_bic)
    explain_refusals(candidates)
    before, named, after = np.sqrt(sse / n_total)
    converter, converter_source = stated_converter(dataset)
    doc = {
        "baseline": {"rmse_v": float(before)},
        "findings": [f.as_dict() for f in findings],
        "unexplained": sorted(unexplained, key=lambda u: u["evidence"]["delta_bic"]),
        "gain": _gain(before, after),
        "gain_named": _gain(before, named),
        "noise_floor": _floor_summary(floors),
        "candidates": candidates,
        "channels": channels,
        "logger": {"antialias_hz": corner, "source": source, "t_ref_c": replay.t_ref_c,
                   "fp_latch_s": replay.fp_latch, "clock_tolerance_ppm": tol,
                   "converter": {"range_v": list(converter.range_v), "bits": converter.bits,
                                 "step_v": converter.step_v, "source": converter_source}},
        "residuals": views,
        "steps_skipped": list(replay.skipped),
        "steps_clipped": replay.clipped,
    }
    doc["verdict"] = verdict(doc)
    return doc


def _residual_story(ctx: Context, nominal: Fit, baseline: Fit, outcome: Outcome,
                    figures: dict[str, str] | None) -> tuple[dict[str, Any],
                                                          list[dict[str, Any]], dict[str, Any]]:
    """One channel's noise floor, the residual above it (an ``other`` entry) and its views.

    Views and figures compare the nominal model with the model the JSON reports — named
    effects and generic extensions together — so the report shows what was found.
    """
    r0, r1 = _residuals(ctx, nominal), joint_residuals(ctx, outcome.joint)
    floor = noise_floor({sr.step.id: r1[sr.index] for sr in ctx.replay.steps}, ctx.replay.dt_s)
    final_rms = held_out_rmse(outcome.joint.fit)
    rest = residual_entry(ctx, r1, floor, final_rms)
    views = residual_views(ctx, r0, r1, floor)
    if figures is not None:
        figures.update(residual_figures(ctx, r0, r1, views))
    return _floor_view(floor, rmse(baseline), final_rms), [rest] if rest else [], views


def _residuals(ctx: Context, fit: Fit) -> dict[int, np.ndarray]:
    """Measured − the prediction of ``fit``, per step index (V)."""
    pred = predict(ctx.replay, ctx.info, fit)
    return {i: ctx.targets[i] - pred[i] for i in pred}


def _floor_view(floor: NoiseFloor, nominal_rms_v: float, final_rms_v: float) -> dict[str, Any]:
    """One channel's noise floor against its held-out residual, nominal and final model."""
    return {"rms_v": floor.rms_v, "residual_rms_v_nominal": nominal_rms_v,
            "residual_rms_v": final_rms_v, "ratio_nominal": floor.ratio(nominal_rms_v),
            "ratio": floor.ratio(final_rms_v), "per_step_v": floor.per_step_v}


def _floor_summary(floors: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """The worst channel's ratio (the verdict's), how the floor was read, every channel."""
    worst = max(floors.values(), key=lambda v: v["ratio"])
    return {"method": METHOD, "explained_ratio": EXPLAINED_RATIO, "rms_v": worst["rms_v"],
            "residual_rms_v": worst["residual_rms_v"], "ratio": worst["ratio"],
            "channels": floors}


def _apply_withdrawals(result: ChannelResult, outcome: Outcome) -> None:
    """Drop the named findings the backward pass withdrew; say why in their candidate rows."""
    result.findings = [f for f in result.findings if f.effect not in outcome.withdrawn]
    for key, row in result.candidates.items():
        reason = outcome.withdrawn.get(row["effect"])
        if reason is not None and row.get("accepted"):
            result.candidates[key] = {**row, "accepted": False, "reason": reason}


def _gain(before: float, after: float) -> dict[str, float]:
    """Held-out RMS before/after, its reduction and the share of variance explained (%)."""
    ratio = after / before if before > 0 else 1.0
    return {"rmse_v_before": float(before), "rmse_v_after": float(after),
            "reduction_pct": float(100.0 * (1.0 - ratio)),
            "variance_explained_pct": float(100.0 * (1.0 - ratio**2))}


def _dedupe_table_effects(findings: list[Finding]) -> list[Finding]:
    """A table effect is one physical cause: keep its strongest sighting over the channels."""
    best: dict[str, Finding] = {}
    out = []
    for f in findings:
        if f.attributed_to != "table":
            out.append(f)
        elif f.effect not in best or f.delta_bic < best[f.effect].delta_bic:
            best[f.effect] = f
    return out + list(best.values())
