"""One story for every output: the verdict, and what a residual above the noise looks like.

The terminal summary, the ``--json`` document and the HTML report all state one of three
results, in the same words (:func:`verdict`):

* ``findings`` — named effects are supported by the evidence;
* ``unexplained`` — no named effect, but the residual holds structure the vocabulary cannot
  name (a generic extension, or a residual above the noise that no generic model fits);
* ``explained`` — nothing beyond the noise: the held-out residual is within
  :data:`~aatest.diagnose.noise_floor.EXPLAINED_RATIO` of the noise floor read from the data.

When the final model's held-out residual stands above that floor, :func:`residual_entry`
reports it as an ``unexplained`` entry of kind ``other``: its level against the noise, and
where it lives — which steps, moving or at rest, a trend over the session, and the strongest
residual lines, each classified against the excitation.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from aatest.diagnose.candidates.base import Context
from aatest.diagnose.noise_floor import EXPLAINED_RATIO, NoiseFloor
from aatest.diagnose.residuals import spectrum_lines

#: steps and lines named in the description of a residual above the noise
_TOP = 3


def _moving_rms(ctx: Context, residuals: dict[int, np.ndarray]) -> dict[str, float | None]:
    """Residual RMS (V) over the steps with the table moving and over those at rest."""
    groups: dict[str, list[np.ndarray]] = {"moving": [], "at_rest": []}
    for sr in ctx.replay.steps:
        moving = sr.inner.moving or sr.outer.moving
        groups["moving" if moving else "at_rest"].append(residuals[sr.index])
    return {f"{k}_rms_v": (float(np.sqrt(np.mean(np.concatenate(v) ** 2))) if v else None)
            for k, v in groups.items()}


def _session_trend(ctx: Context, residuals: dict[int, np.ndarray]) -> dict[str, float]:
    """Straight line of the residual against elapsed session time (steps back to back)."""
    start, t, r = 0.0, [], []
    for sr in ctx.replay.steps:
        t.append(start + sr.time_s)
        r.append(residuals[sr.index])
        start += float(sr.time_s[-1]) + sr.dt_s
    time_h, res = np.concatenate(t) / 3600.0, np.concatenate(r)
    slope, _ = np.polyfit(time_h, res, 1)
    span = float(time_h[-1] - time_h[0])
    return {"slope_v_per_h": float(slope), "change_over_session_v": float(slope * span)}


def _steps(ctx: Context, residuals: dict[int, np.ndarray], floor: NoiseFloor
           ) -> list[dict[str, Any]]:
    """Steps ordered by their residual RMS over their own noise floor, worst first."""
    rows = []
    for sr in ctx.replay.steps:
        rms = float(np.sqrt(np.mean(residuals[sr.index] ** 2)))
        own = floor.per_step_v.get(sr.step.id, floor.rms_v)
        rows.append({"step": sr.step.id, "moving": bool(sr.inner.moving or sr.outer.moving),
                     "rms_v": rms, "noise_floor_v": own,
                     "ratio": rms / own if own > 0 else float("inf")})
    return sorted(rows, key=lambda row: -row["ratio"])


def where_it_lives(ctx: Context, residuals: dict[int, np.ndarray], floor: NoiseFloor
                   ) -> dict[str, Any]:
    """Steps, motion state, session trend and strongest lines of a residual (JSON-ready)."""
    return {"steps": _steps(ctx, residuals, floor)[:_TOP],
            "motion_state": _moving_rms(ctx, residuals),
            "trend": _session_trend(ctx, residuals),
            "lines": spectrum_lines(ctx, residuals)[:_TOP]}


def _where_text(where: dict[str, Any]) -> str:
    steps = ", ".join(f"{s['step']} {s['ratio']:.2g}×" for s in where["steps"])
    state = where["motion_state"]
    parts = [f"worst steps (RMS over their floor) {steps}"]
    if state["moving_rms_v"] is not None and state["at_rest_rms_v"] is not None:
        parts.append(f"moving {1e3 * state['moving_rms_v']:.3g} mV vs at rest "
                     f"{1e3 * state['at_rest_rms_v']:.3g} mV")
    parts.append(f"trend {1e3 * where['trend']['slope_v_per_h']:+.3g} mV/h")
    if where["lines"]:
        parts.append("lines " + ", ".join(
            f"{ln['frequency_hz']:.3f} Hz {1e3 * ln['amplitude_v']:.2g} mV in {ln['step']} "
            f"({ln['class']})" for ln in where["lines"]))
    else:
        parts.append("no narrow line")
    return "; ".join(parts)


def residual_entry(ctx: Context, residuals: dict[int, np.ndarray], floor: NoiseFloor,
                   held_out_rms_v: float) -> dict[str, Any] | None:
    """The ``other`` entry for a final residual above the noise floor (None when within)."""
    ratio = floor.ratio(held_out_rms_v)
    if ratio <= EXPLAINED_RATIO:
        return None
    where = where_it_lives(ctx, residuals, floor)
    n_eff = sum(r.size for r in residuals.values()) / ctx.correlation
    # Gaussian likelihood of the residual's variance against the floor's: what a model that
    # brought the residual down to the noise would gain (no such model was found)
    evidence = {"delta_bic": float(-n_eff * np.log(ratio**2)), "rmse_v_before": held_out_rms_v,
                "rmse_v_after": held_out_rms_v}
    description = (f"residual not explained: {1e3 * held_out_rms_v:.3g} mV RMS held-out = "
                   f"{ratio:.2f}× the noise floor {1e3 * floor.rms_v:.3g} mV; no generic model "
                   f"fits it; {_where_text(where)}")
    extension = {"model": None, "noise_floor_v": floor.rms_v, "ratio": ratio, "where": where}
    return {"kind": "other", "description": description, "evidence": evidence,
            "extension": extension, "channel": ctx.info.channel}


def verdict(doc: dict[str, Any]) -> dict[str, str]:
    """The headline shared by the terminal, the JSON and the report (kind + sentence)."""
    findings, unexplained = doc["findings"], doc.get("unexplained") or []
    floor = doc.get("noise_floor") or {}
    ratio = floor.get("ratio")
    level = (f"; after the model the held-out residual is {1e3 * floor['residual_rms_v']:.3g} "
             f"mV RMS = {ratio:.2f}× the noise floor {1e3 * floor['rms_v']:.3g} mV read from "
             "the data" if ratio is not None else "")
    if findings:
        names = ", ".join(dict.fromkeys(f["effect"] for f in findings))
        more = ("; beyond them, structure the vocabulary cannot name (unexplained, below)"
                if unexplained else "")
        return {"kind": "findings",
                "headline": f"effects supported by the evidence: {names}{more}{level}"}
    if unexplained:
        return {"kind": "unexplained",
                "headline": ("no named effect is supported by the evidence, but the residual "
                             "holds structure the vocabulary cannot name (unexplained, below)"
                             + level)}
    return {"kind": "explained",
            "headline": ("nothing beyond the noise: the nominal model explains the data" + level)}
