"""The diagnose pipeline on a Dataset: replay, residuals, candidates, selection, gain.

Returns the contract document (contracts.md §4) plus extra keys: per-channel calibration,
residual views, the logger chain assumed, and the not-testable reasons.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from aatest.engine.dataset import Dataset
from aatest.plugins.diagnose.alignment import nominal_fit
from aatest.plugins.diagnose.design import Fit, predict
from aatest.plugins.diagnose.effects.base import Context, replace_spec
from aatest.plugins.diagnose.effects.logger import (
    DEFAULT_CLOCK_TOLERANCE_PPM,
    clock_drift,
    excess_noise,
    one_clock_fit,
    phase_trend_drift,
)
from aatest.plugins.diagnose.figures import residual_figures
from aatest.plugins.diagnose.logger_chain import channel_info, logger_options, targets_of
from aatest.plugins.diagnose.replay import Replay, replay_dataset
from aatest.plugins.diagnose.residuals import residual_views
from aatest.plugins.diagnose.selection import (
    BIC_THRESHOLD,
    ChannelResult,
    Finding,
    correlation_factor,
    forward_select,
    rmse,
)



def diagnose_channel(dataset: Dataset, replay: Replay, channel: str,
                     corner: float | None) -> tuple[ChannelResult, Context]:
    """Nominal fit, noise correlation and forward selection for one channel."""
    ctx = Context(replay, channel_info(dataset, channel, corner, replay.t_ref_c),
                  targets_of(replay, channel), None)  # type: ignore[arg-type]
    nominal = nominal_fit(ctx)
    ctx.current = nominal
    ctx.correlation = correlation_factor(ctx, nominal)
    findings, rows = forward_select(ctx)
    return ChannelResult(channel, nominal, ctx.current, findings, rows, ctx.correlation), ctx


def _drift_finding(ctx: Context, tolerance_ppm: float) -> tuple[Finding | None, dict[str, Any]]:
    """Clock drift from the sync edges (or the phase trend without them), beyond tolerance."""
    row: dict[str, Any] = {"effect": "clock_drift", "accepted": False, "testable": True,
                           "attributed_to": "logger", "tolerance_ppm": tolerance_ppm}
    est = clock_drift(ctx)
    if est is not None:
        drift, u, source = est.drift_ppm, est.u_ppm, "sync edges"
        ci = [drift - 1.96 * u, drift + 1.96 * u]
        before, after = one_clock_fit(ctx, drift), ctx.current
    else:
        trend = phase_trend_drift(ctx)
        if trend is None:
            return None, {**row, "delta_bic": None, "testable": False,
                          "reason": "no sync edges and no sine step to show a phase trend"}
        drift, ci, after = trend
        before, source = ctx.current, "phase trend (no sync edges)"
    n_eff = before.n / ctx.correlation
    dbic = float(n_eff * np.log(max(after.sse_held_out, 1e-300) / max(before.sse_held_out, 1e-300))
                 + np.log(n_eff))
    row |= {"delta_bic": dbic, "parameters": {"drift_ppm": drift}, "source": source}
    significant = ci[0] > 0 or ci[1] < 0
    if abs(drift) <= tolerance_ppm or not significant or dbic > -BIC_THRESHOLD and source != "sync edges":
        row["reason"] = f"|drift| within the rig's clock tolerance ({tolerance_ppm:g} ppm)"
        return None, row
    row["accepted"] = True
    return Finding("clock_drift", "all", {"drift_ppm": drift}, {"drift_ppm": ci}, dbic,
                   rmse(before), rmse(after), "logger", {"source": source}), row


def _with_drift(ctx: Context, result: ChannelResult, drift: Finding | None) -> tuple[Fit, Fit]:
    """(baseline, final) fits with the clock drift taken into account.

    Nominal means one clock (contracts.md §4 step 1): with edges the data were drift-corrected
    by the sync, so the one-clock baseline is the nominal replay warped by the drift; from the
    phase trend the data are on one clock, so the extended model carries the warp.
    """
    if drift is None:
        return result.nominal, result.final
    ppm = drift.parameters["drift_ppm"]
    if drift.extra.get("source") == "sync edges":
        return ctx.fit(replace_spec(result.nominal.spec, warp_ppm=ppm)), result.final
    return result.nominal, ctx.fit(replace_spec(result.final.spec, warp_ppm=-ppm, delay_s=0.0,
                                                step_shift_s=(), warp_from_start=True))


def _noise_finding(ctx: Context, stated_noise_v: float) -> tuple[Finding | None, dict[str, Any]]:
    pred = predict(ctx.replay, ctx.info, ctx.current)
    residuals = {i: ctx.targets[i] - pred[i] for i in pred}
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


def diagnose_dataset(dataset: Dataset, clock_tolerance_ppm: float | None = None,
                     figures: dict[str, str] | None = None) -> dict[str, Any]:
    """Run the whole pipeline; return the diagnosis document (contract keys plus extras).

    ``figures``, when given, receives the residual-view SVGs of the report (title → SVG).
    """
    replay = replay_dataset(dataset)
    tol = clock_tolerance_ppm or float(dataset.metadata.get("clock_tolerance_ppm")
                                       or DEFAULT_CLOCK_TOLERANCE_PPM)
    options = logger_options(dataset, replay)
    if len(options) > 1:  # ambiguous logger chain: the one needing fewer effects wins
        docs = [_diagnose_with(dataset, replay, corner, reason, tol) for corner, reason in options]
        best = min(range(len(docs)), key=lambda i: (len(docs[i]["findings"]),
                                                    docs[i]["gain"]["rmse_v_after"]))
        if figures is None:
            return docs[best]
        options = [options[best]]
    corner, reason = options[0]
    return _diagnose_with(dataset, replay, corner, reason, tol, figures)


def _diagnose_with(dataset: Dataset, replay: Replay, corner: float | None, source: str,
                   tol: float, figures: dict[str, str] | None = None) -> dict[str, Any]:
    """The diagnosis document for one assumed logger chain (``figures`` filled when given)."""
    findings: list[Finding] = []
    candidates: list[dict[str, Any]] = []
    channels, views = [], {}
    sse_before = sse_after = 0.0
    n_total = 0
    drift_f: Finding | None = None
    for i, channel in enumerate(replay.channels):
        result, ctx = diagnose_channel(dataset, replay, channel, corner)
        findings += result.findings
        candidates += list(result.candidates.values())
        noise_f, noise_row = _noise_finding(ctx, dataset.sensor(channel).noise_rms_v)
        candidates.append(noise_row)
        findings += [noise_f] if noise_f else []
        if i == 0:
            drift_f, drift_row = _drift_finding(ctx, tol)
            candidates.append(drift_row)
            findings += [drift_f] if drift_f else []
        baseline, result.final = _with_drift(ctx, result, drift_f)
        sse_before += baseline.sse_held_out
        sse_after += result.final.sse_held_out
        n_total += result.final.n
        channels.append(_calibration(result, ctx))
        views[channel] = residual_views(ctx, result.nominal, result.final)
        if figures is not None:
            figures.update(residual_figures(ctx, result.nominal, result.final, views[channel]))
    findings = sorted(_dedupe_table_effects(findings), key=lambda f: f.delta_bic)
    before, after = np.sqrt(sse_before / n_total), np.sqrt(sse_after / n_total)
    return {
        "baseline": {"rmse_v": float(before)},
        "findings": [f.as_dict() for f in findings],
        "gain": _gain(before, after),
        "candidates": candidates,
        "channels": channels,
        "logger": {"antialias_hz": corner, "source": source, "t_ref_c": replay.t_ref_c,
                   "fp_latch_s": replay.fp_latch, "clock_tolerance_ppm": tol},
        "residuals": views,
        "steps_skipped": list(replay.skipped),
    }


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
