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

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy import optimize

from aatest.diagnose.alignment import realigned
from aatest.diagnose.candidates import Candidate, vocabulary
from aatest.diagnose.candidates.base import CandidateFit, Context, dynamic_peak_dps2
from aatest.diagnose.candidates.shape import DAMPING_BOUNDS, MAX_DELAY_S, MAX_NATURAL_HZ
from aatest.diagnose.design import predict
from aatest.diagnose.gram import Fit
from aatest.diagnose.spec import Spec
from aatest.numerics import TINY

BIC_THRESHOLD = 10.0
MIN_REDUCTION = 0.003
MAX_FINDINGS_PER_CHANNEL = 6
HOPELESS_BIC = 5.0
#: an acceptance that lowers the held-out RMS by this share re-tests the dormant candidates
WAKE_REDUCTION = 0.1
#: effects with nonlinear shape parameters that trade with each other
SHAPE_EFFECTS = frozenset({"time_delay", "hysteresis", "saturation", "sensor_dynamics",
                           "amplitude_damping"})
#: joint refinement: initial simplex step (share of each value) and iterations per parameter
POLISH_STEP = 0.1
POLISH_ITER_PER_AXIS = 30
#: cost of a parameter outside its bounds (finite, so simplex arithmetic stays defined)
_OUTSIDE = 1e200
#: Welch segment (samples) of the noise-correlation estimate, and the band's lower edge (Hz)
_NPERSEG = 1024
_LOW_BAND_HZ = 2.0
#: nonlinear parameters each effect adds on top of its design columns
SHAPE_PARAMS = {"time_delay": 1, "sensor_dynamics": 2, "hysteresis": 1, "saturation": 1,
                "rate_ripple": 1, "motor_vibration": 1, "amplitude_damping": 1,
                "rotor_stiction": 1}


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
    ratio = max(new.sse_held_out, TINY) / max(old.sse_held_out, TINY)
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


def forward_select(ctx: Context, candidates: tuple[Candidate, ...] | None = None
                   ) -> tuple[list[Finding], dict[str, dict[str, Any]]]:
    """Accept effects one by one while the best remaining one passes the stopping rule.

    ``candidates`` defaults to the built-ins plus the installed effect plugins.
    """
    candidates = vocabulary() if candidates is None else candidates
    SHAPE_PARAMS.update({c.effect: c.shape_params for c in candidates if c.shape_params})
    rows: dict[str, dict[str, Any]] = {}
    findings: list[Finding] = []
    accepted: dict[str, int] = {}
    remaining = list(candidates)
    dormant: list[Candidate] = []  # no evidence yet: re-tested once the residual has shrunk
    first_dbic: dict[str, float] = {}  # each candidate's ΔBIC on the model it first met
    while remaining and len(findings) < MAX_FINDINGS_PER_CHANNEL:
        scored = []
        for cand in remaining:
            if _waiting(ctx, cand):
                rows[cand.effect] = _waiting_row(ctx, cand)
                continue
            cf, reason = _evaluate(ctx, cand)
            if cf is None:
                rows[cand.effect] = {"effect": cand.effect, "delta_bic": None, "accepted": False,
                                     "testable": False, "reason": reason,
                                     "channel": ctx.info.channel}
                continue
            dbic = delta_bic(ctx, cf.fit, ctx.current, cand.effect)
            rows[cand.effect] = _row(cf, dbic, ctx)
            first_dbic.setdefault(cand.effect, dbic)
            scored.append((dbic, cand, cf))
        dormant += [c for c in remaining if rows[c.effect]["testable"]
                    and _hopeless(rows[c.effect])]
        remaining = [c for c in remaining if _waiting(ctx, c) or (
            rows[c.effect]["testable"] and not _hopeless(rows[c.effect]))]
        passing = [item for item in scored if _passes(item[2], item[0], ctx)]
        if not passing:
            break
        dbic, cand, cf = min(passing, key=lambda item: item[0])
        if rmse(cf.fit) < (1.0 - WAKE_REDUCTION) * rmse(ctx.current):
            # a large effect hid the small ones: what had no evidence beside it is re-tested
            remaining += [c for c in dormant if c.effect != cand.effect]
            dormant = []
        findings.append(_finding(ctx, cf, dbic))
        accepted[cand.effect] = accepted.get(cand.effect, 0) + 1
        rows[f"{cand.effect}#{accepted[cand.effect]}"] = {**rows.pop(cand.effect), "accepted": True}
        ctx.accepted.add(cand.effect)
        ctx.current = polish_shapes(ctx, _adopt(ctx, cand, cf), cand.effect)
        remaining = [c for c in remaining
                     if c.effect != cand.effect or accepted[c.effect] < c.repeatable]
    _sync_shape_parameters(ctx.current.spec, findings)
    _mirror_misalignment(ctx, rows, findings)
    _refusal_reasons(ctx, rows, first_dbic, findings)
    return findings, rows


def _waiting(ctx: Context, cand: Candidate) -> bool:
    """Whether ``cand`` extends an effect not (yet) in the model: it is not tested before."""
    return cand.requires is not None and cand.requires not in ctx.accepted


def _waiting_row(ctx: Context, cand: Candidate) -> dict[str, Any]:
    """The row of a waiting candidate: testable or not by its own check, but not tested."""
    reason = cand.testable(ctx)
    return {"effect": cand.effect, "delta_bic": None, "accepted": False,
            "testable": reason is None, "channel": ctx.info.channel,
            "reason": reason or f"not tested: it extends {cand.requires}, which the data do "
                                "not support"}


def _refusal_reasons(ctx: Context, rows: dict[str, dict[str, Any]],
                     first_dbic: dict[str, float], findings: list[Finding]) -> None:
    """Say why each candidate with favourable evidence (ΔBIC < 0) was not accepted."""
    accepted = ", ".join(dict.fromkeys(f.effect for f in findings))
    before = rmse(ctx.current)
    for row in rows.values():
        dbic = row.get("delta_bic")
        if row.get("accepted") or row.get("reason") or dbic is None or dbic >= 0:
            continue
        first = first_dbic.get(row["effect"], dbic)
        drop_pct = 100.0 * (1.0 - row.get("rmse_v_after", before) / before) if before else 0.0
        if first < -BIC_THRESHOLD and dbic > -BIC_THRESHOLD and findings:
            row["reason"] = (f"absorbed by {accepted} in the joint fit: ΔBIC {first:.1f} "
                             f"before them, {dbic:.1f} beside them")
        elif dbic > -BIC_THRESHOLD:
            row["reason"] = (f"below its detectable size: ΔBIC {dbic:.1f} does not reach "
                             f"−{BIC_THRESHOLD:g} (very strong evidence)")
        elif drop_pct < 100.0 * MIN_REDUCTION:
            row["reason"] = (f"below its detectable size: lowers the held-out RMS by only "
                             f"{drop_pct:.2f} % (a material effect: ≥ {100 * MIN_REDUCTION:g} %)")
        elif len(findings) >= MAX_FINDINGS_PER_CHANNEL:
            row["reason"] = (f"not accepted: the channel already holds "
                             f"{MAX_FINDINGS_PER_CHANNEL} findings")


def explain_refusals(candidates: list[dict[str, Any]]) -> None:
    """Last word for any favourable candidate row still without a reason (all channels)."""
    for row in candidates:
        dbic = row.get("delta_bic")
        if row.get("accepted") or row.get("reason") or dbic is None or dbic >= 0:
            continue
        row["reason"] = (f"refused by the stopping rule: ΔBIC {dbic:.1f} with the model it was "
                         f"last tested on (accepted: ΔBIC < −{BIC_THRESHOLD:g} and a "
                         f"≥ {100 * MIN_REDUCTION:g} % lower held-out RMS)")


def _shape_axes(ctx: Context) -> list[tuple[Callable[[Spec], float],
                                            Callable[[Spec, float], Spec], float, float]]:
    """(get, set, lower, upper bound) of every accepted shape parameter."""
    peak = dynamic_peak_dps2(ctx) if ctx.dynamic_steps else 1.0
    axes: list[tuple[Callable[[Spec], float], Callable[[Spec, float], Spec], float, float]] = []
    if "time_delay" in ctx.accepted:
        axes.append((lambda s: s.delay_s, lambda s, v: replace(s, delay_s=v), 0.0, MAX_DELAY_S))
    if "hysteresis" in ctx.accepted:
        axes.append((lambda s: s.hysteresis_dps2, lambda s, v: replace(s, hysteresis_dps2=v),
                     0.0, 0.1 * peak))
    if "saturation" in ctx.accepted:
        axes.append((lambda s: s.saturation_dps2 or peak,
                     lambda s, v: replace(s, saturation_dps2=v), 0.3 * peak, peak))
    if "sensor_dynamics" in ctx.accepted:
        axes.append((lambda s: s.dynamics[0] if s.dynamics else 100.0,
                     lambda s, v: replace(s, dynamics=(v, s.dynamics[1] if s.dynamics else 0.7)),
                     0.5, MAX_NATURAL_HZ))
        axes.append((lambda s: s.dynamics[1] if s.dynamics else 0.7,
                     lambda s, v: replace(s, dynamics=(s.dynamics[0] if s.dynamics else 100.0, v)),
                     DAMPING_BOUNDS[0], DAMPING_BOUNDS[1]))
    if "amplitude_damping" in ctx.accepted:
        axes.append((_damping_at_decade, _put_damping_at_decade, *DAMPING_BOUNDS))
    return axes


def _damping_at_decade(spec: Spec) -> float:
    """ζ one decade above the reference amplitude: the amplitude dependence as a positive
    parameter (the joint refinement scales each parameter by its value)."""
    if spec.amplitude_damping is None or spec.dynamics is None:
        return 0.7
    return spec.dynamics[1] + spec.amplitude_damping[0]


def _put_damping_at_decade(spec: Spec, value: float) -> Spec:
    if spec.amplitude_damping is None or spec.dynamics is None:
        return spec
    return replace(spec, amplitude_damping=(round(value - spec.dynamics[1], 12),
                                            spec.amplitude_damping[1]))


def polish_shapes(ctx: Context, fit: Fit, added: str) -> Fit:
    """Re-fit the accepted shape parameters together (joint refinement after an acceptance).

    Each effect was fitted with the ones before it held fixed; look-alikes (a delay and the
    lag of sensor dynamics, hysteresis and a delay, clipping and a cubic) trade parameters,
    and a shape fitted before a later linear effect (a cubic, a temperature term) was in the
    model is biased by its absence. So after every acceptance (``added``) the accepted shape
    parameters are re-optimised jointly (Nelder–Mead on parameters scaled by their current
    values, bounded) on the in-sample SSE — unless ``added`` is the only one, just fitted.
    """
    shapes = ctx.accepted & SHAPE_EFFECTS
    if not shapes or shapes == {added}:
        return fit
    axes = _shape_axes(ctx)
    x0 = np.array([max(get(fit.spec), 1e-12) for get, _, _, _ in axes])

    def spec_of(u: np.ndarray) -> Spec | None:
        spec = fit.spec
        for (_, put, lo, hi), v in zip(axes, u * x0, strict=True):
            if not lo <= v <= hi:
                return None
            spec = put(spec, round(float(v), 12))
        return spec

    def cost(u: np.ndarray) -> float:
        spec = spec_of(u)
        return _OUTSIDE if spec is None else ctx.fit(spec).sse_in

    ones = np.ones(len(axes))
    simplex = np.vstack([ones] + [ones + POLISH_STEP * np.eye(len(axes))[j]
                                  for j in range(len(axes))])
    res = optimize.minimize(cost, ones, method="Nelder-Mead",
                            options={"initial_simplex": simplex, "xatol": 1e-4,
                                     "fatol": 1e-9 * fit.sse_in,
                                     "maxiter": POLISH_ITER_PER_AXIS * len(axes)})
    spec = spec_of(np.asarray(res.x))
    best = ctx.fit(spec) if spec is not None else fit
    return best if best.sse_in < fit.sse_in else fit


def _sync_shape_parameters(spec: Spec, findings: list[Finding]) -> None:
    """Shape findings report the jointly re-fitted values (intervals moved with them)."""
    values: dict[str, dict[str, float | None]] = {
        "time_delay": {"delay_s": spec.delay_s},
        "hysteresis": {"half_width_dps2": spec.hysteresis_dps2},
        "saturation": {"limit_dps2": spec.saturation_dps2},
        "sensor_dynamics": {"natural_frequency_hz": spec.dynamics[0] if spec.dynamics else None,
                            "damping": spec.dynamics[1] if spec.dynamics else None},
        "amplitude_damping": {"damping_per_decade": spec.amplitude_damping[0]
                              if spec.amplitude_damping else None}}
    for f in findings:
        for key, new in values.get(f.effect, {}).items():
            old = f.parameters.get(key)
            if new is None or old is None or new == old:
                continue
            f.parameters[key] = float(new)
            if key in f.ci95:
                f.ci95[key] = [v + float(new) - old for v in f.ci95[key]]


def _adopt(ctx: Context, cand: Candidate, cf: CandidateFit) -> Fit:
    """The accepted fit becomes the current model (time-family fits drop the nuisance; an
    accepted timing effect gets them re-fitted on it, :func:`realigned`)."""
    return realigned(ctx, cf.fit, cand.effect)


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
