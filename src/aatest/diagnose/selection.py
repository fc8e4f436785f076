"""Name the cause: held-out scoring, ΔBIC and forward selection with a strict stopping rule.

Every candidate extends the current model; it is scored on held-out data (two folds of
alternating time blocks in every step: fit on one, score on the other) with a BIC that counts
*independent* samples — the residual of a filtered logger is correlated over several samples,
so n_eff = n/ν with ν from the residual spectrum. The best candidate is accepted when

1. it is not vetoed by its own physics (a lag within one sample, a lead that is a lag, …),
2. ΔBIC < −:data:`BIC_THRESHOLD` (very strong evidence, Kass & Raftery), and
3. it lowers the held-out RMS by at least :data:`MIN_REDUCTION` (a material effect),

then the remaining candidates are re-fitted on top of it, until none passes. Look-alikes
compete on the same held-out score, so the effect whose signature fits wins.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from aatest.diagnose.design import Fit, predict
from aatest.diagnose.effects import CANDIDATES, Candidate
from aatest.diagnose.effects.base import CandidateFit, Context

BIC_THRESHOLD = 10.0
MIN_REDUCTION = 0.003
MAX_FINDINGS_PER_CHANNEL = 6
HOPELESS_BIC = 5.0
#: Welch segment (samples) of the noise-correlation estimate, and the band's lower edge (Hz)
_NPERSEG = 1024
_LOW_BAND_HZ = 2.0
#: nonlinear parameters each effect adds on top of its design columns
SHAPE_PARAMS = {"time_delay": 1, "sensor_dynamics": 2, "hysteresis": 1, "saturation": 1,
                "rate_ripple": 1, "motor_vibration": 1}


@dataclass
class Finding:
    """An accepted effect with its evidence (contract JSON + extras)."""

    effect: str
    channel: str
    parameters: dict[str, float]
    ci95: dict[str, list[float]]
    delta_bic: float
    rmse_v_before: float
    rmse_v_after: float
    attributed_to: str = "sensor"
    extra: dict[str, Any] = field(default_factory=dict)
    #: clock findings only: how the one-clock baseline / the extended replay are warped
    #: (ppm; final: (ppm, about the record start)); internal, not part of the JSON
    baseline_warp_ppm: float | None = field(default=None, repr=False)
    final_warp: tuple[float, bool] | None = field(default=None, repr=False)

    def as_dict(self) -> dict[str, Any]:
        return {"effect": self.effect, "parameters": self.parameters, "ci95": self.ci95,
                "evidence": {"delta_bic": self.delta_bic, "rmse_v_before": self.rmse_v_before,
                             "rmse_v_after": self.rmse_v_after},
                "channel": self.channel, "attributed_to": self.attributed_to, **self.extra}


@dataclass
class ChannelResult:
    """Diagnosis of one sensor channel."""

    channel: str
    nominal: Fit
    final: Fit
    findings: list[Finding]
    candidates: dict[str, dict[str, Any]]
    correlation: float


def rmse(fit: Fit) -> float:
    """Held-out RMS residual (V)."""
    return float(np.sqrt(fit.sse_held_out / max(fit.n, 1)))


def correlation_factor(ctx: Context, fit: Fit) -> float:
    """ν = n/n_eff of the residual: low-frequency PSD over the white level of its variance."""
    from scipy import signal

    fs = 1.0 / ctx.replay.dt_s
    pred = predict(ctx.replay, ctx.info, fit)
    ratios = []
    for s in ctx.replay.steps:
        r = ctx.targets[s.index] - pred[s.index]
        if r.size < 2 * _NPERSEG:
            continue
        f, p = signal.welch(r, fs=fs, nperseg=_NPERSEG,
                            detrend=lambda x: np.asarray(signal.detrend(x, type="linear")))
        low = (f > _LOW_BAND_HZ) & (f < 0.05 * fs)
        ratios.append(float(np.median(p[low])) / (2.0 * r.var() / fs))
    return float(np.clip(np.median(ratios), 1.0, 50.0)) if ratios else 1.0


def delta_bic(ctx: Context, new: Fit, old: Fit, effect: str) -> float:
    """BIC(new) − BIC(old) on held-out SSE with n_eff independent samples."""
    n_eff = new.n / ctx.correlation
    dk = (new.k - old.k) + SHAPE_PARAMS.get(effect, 0)
    ratio = max(new.sse_held_out, 1e-300) / max(old.sse_held_out, 1e-300)
    return float(n_eff * np.log(ratio) + dk * np.log(n_eff))


def _evaluate(ctx: Context, cand: Candidate) -> tuple[CandidateFit | None, str | None]:
    reason = cand.testable(ctx)
    if reason is not None:
        return None, reason
    return cand.fit(ctx), None


def _row(cf: CandidateFit, dbic: float, ctx: Context) -> dict[str, Any]:
    row: dict[str, Any] = {"effect": cf.effect, "delta_bic": dbic, "accepted": False,
                           "testable": True, "parameters": cf.parameters,
                           "rmse_v_after": rmse(cf.fit), "attributed_to": cf.attributed_to,
                           "channel": ctx.info.channel}
    if cf.veto:
        row["reason"] = cf.veto
    return row


def _hopeless(row: dict[str, Any]) -> bool:
    """No evidence at all (ΔBIC > +5): re-fitting on top of another effect will not change it."""
    return row["delta_bic"] is not None and row["delta_bic"] > HOPELESS_BIC


def _passes(cf: CandidateFit, dbic: float, ctx: Context) -> bool:
    before, after = rmse(ctx.current), rmse(cf.fit)
    return (cf.veto is None and dbic < -BIC_THRESHOLD
            and after < (1.0 - MIN_REDUCTION) * before)


def forward_select(ctx: Context, candidates: tuple[Candidate, ...] = CANDIDATES
                   ) -> tuple[list[Finding], dict[str, dict[str, Any]]]:
    """Accept effects one by one while the best remaining one passes the stopping rule."""
    rows: dict[str, dict[str, Any]] = {}
    findings: list[Finding] = []
    accepted: dict[str, int] = {}
    remaining = list(candidates)
    while remaining and len(findings) < MAX_FINDINGS_PER_CHANNEL:
        scored = []
        for cand in remaining:
            cf, reason = _evaluate(ctx, cand)
            if cf is None:
                rows[cand.effect] = {"effect": cand.effect, "delta_bic": None, "accepted": False,
                                     "testable": False, "reason": reason,
                                     "channel": ctx.info.channel}
                continue
            dbic = delta_bic(ctx, cf.fit, ctx.current, cand.effect)
            rows[cand.effect] = _row(cf, dbic, ctx)
            scored.append((dbic, cand, cf))
        remaining = [c for c in remaining if rows[c.effect]["testable"]
                     and not _hopeless(rows[c.effect])]
        passing = [item for item in scored if _passes(item[2], item[0], ctx)]
        if not passing:
            break
        dbic, cand, cf = min(passing, key=lambda item: item[0])
        findings.append(_finding(ctx, cf, dbic))
        accepted[cand.effect] = accepted.get(cand.effect, 0) + 1
        rows[f"{cand.effect}#{accepted[cand.effect]}"] = {**rows.pop(cand.effect), "accepted": True}
        ctx.current = _adopt(ctx, cand, cf)
        remaining = [c for c in remaining
                     if c.effect != cand.effect or accepted[c.effect] < c.repeatable]
    _mirror_misalignment(ctx, rows, findings)
    return findings, rows


def _adopt(ctx: Context, cand: Candidate, cf: CandidateFit) -> Fit:
    """The accepted fit becomes the current model (time-family fits drop the nuisance)."""
    return cf.fit


def _finding(ctx: Context, cf: CandidateFit, dbic: float) -> Finding:
    extra = dict(cf.extra)
    return Finding(cf.effect, ctx.info.channel, cf.parameters, cf.ci95, dbic, rmse(ctx.current),
                   rmse(cf.fit), cf.attributed_to, extra)


def _mirror_misalignment(ctx: Context, rows: dict[str, dict[str, Any]],
                         findings: list[Finding]) -> None:
    """Misalignment and cross-axis share one signature in one mounting; see the module rule."""
    cross = rows.get("cross_axis") or rows.get("cross_axis#1")
    if cross is None or not cross.get("testable"):
        rows["misalignment"] = {"effect": "misalignment", "delta_bic": None, "accepted": False,
                                "testable": False, "channel": ctx.info.channel,
                                "reason": (cross or {}).get("reason", "no cross-axis excitation")}
        return
    rows["misalignment"] = {**cross, "effect": "misalignment", "accepted": False,
                            "reason": ("same signature as cross_axis in one mounting; the cross "
                                       "response is reported as cross_axis with its equivalent "
                                       "tilt (rule: aatest.diagnose docstring)")}
    for f in findings:
        if f.effect == "cross_axis":
            tilt = f.extra.get("equivalent_misalignment", {})
            rows["misalignment"]["parameters"] = tilt
            f.extra["look_alike"] = {"effect": "misalignment", "parameters": tilt}
