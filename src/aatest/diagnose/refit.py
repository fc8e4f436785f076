"""The joint model after selection: backward elimination, marginal evidence, joint intervals.

Forward selection accepts effects one at a time, each on top of those before it; an early
acceptance can become redundant once later effects (named or generic) are in the model. The
backward pass re-tests every accepted effect against the joint model — all named effects and
generic extensions fitted together on held-out blocks — weakest first, and withdraws those
whose removal no longer costs ΔBIC < −``BIC_THRESHOLD``. Every effect kept gets its own
marginal evidence (held-out ΔBIC and RMS when it alone is removed) and, for the linear ones,
parameters with 95 % intervals from the joint fit (reported as the finding's parameters; the
value at acceptance held later effects and the unnamed structure at zero).

Removing a timing effect does not give the nominal model back its alignment nuisance, so its
marginal ΔBIC is, if anything, overstated: timing effects are never withdrawn wrongly.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from aatest.diagnose.candidates.base import Context, linear_ci
from aatest.diagnose.candidates.plugins import joint_parameters
from aatest.diagnose.joint import Joint, bic_change, held_out_rmse, joint_fit
from aatest.diagnose.selection import BIC_THRESHOLD, SHAPE_PARAMS, Finding
from aatest.diagnose.spec import Spec
from aatest.effects import spec_token

_LINEAR_PARAMS = {"bias_temperature": ("bias_temperature", "coefficient_v_per_c", False),
                  "scale_temperature": ("scale_temperature", "coefficient_per_c", True),
                  "nonlinearity_cubic": ("nonlinearity_cubic", "c3", True),
                  "g_sensitivity": ("g_sensitivity", "coefficient_dps2_per_g", True),
                  "jerk_sensitivity": ("jerk_sensitivity", "coefficient_v_per_dps3", False),
                  "jerk_distortion": ("jerk_distortion", "coefficient_v_per_dps3_squared",
                                      False)}
_SHAPE_RESET: dict[str, dict[str, Any]] = {
    "saturation": {"saturation_dps2": None}, "hysteresis": {"hysteresis_dps2": 0.0},
    "sensor_dynamics": {"dynamics": None}, "time_delay": {"delay_s": 0.0},
    "rate_ripple": {"ripple_cpd": (), "ripple_motion_deg": ()},
    "motor_vibration": {"vibration_hz": ()}, "amplitude_damping": {"amplitude_damping": None}}


def without(spec: Spec, effect: str) -> Spec | None:
    """``spec`` with a named effect switched off (None when it is not part of the spec)."""
    token = spec_token(effect)  # a plugin effect (aatest.effects), even one shadowing a built-in
    if token in spec.linear:
        return replace(spec, linear=spec.linear - {token},
                       plugin_shape=tuple(e for e in spec.plugin_shape if e[0] != effect))
    if effect in _LINEAR_PARAMS or effect == "cross_axis":
        return replace(spec, linear=spec.linear - {effect})
    if effect in _SHAPE_RESET:
        return replace(spec, **_SHAPE_RESET[effect])
    if effect == "rotor_stiction":  # a searched break-away rate and a column of its own
        return replace(spec, linear=spec.linear - {effect}, stiction_dps=0.0)
    return None


def _marginal(ctx: Context, joint: Joint, effect: str) -> tuple[float, float, Spec] | None:
    """(ΔBIC of keeping the effect, held-out RMS without it, the spec without it)."""
    reduced = without(joint.spec, effect)
    if reduced is None:
        return None
    fit = joint_fit(ctx, reduced, joint.generics)
    return bic_change(ctx, joint.fit, fit, SHAPE_PARAMS.get(effect, 0)), held_out_rmse(fit), reduced


def backward_pass(ctx: Context, joint: Joint, findings: list[Finding]) -> dict[str, str]:
    """Withdraw accepted effects the joint model does not need (weakest first).

    ``joint`` is updated in place; kept findings get ``marginal`` evidence and, for linear
    effects, ``joint_fit`` parameters with 95 % intervals. Returns effect → reason withdrawn.
    """
    withdrawn: dict[str, str] = {}
    for f in sorted(findings, key=lambda f: -f.delta_bic):
        m = _marginal(ctx, joint, f.effect)
        if m is not None and m[0] > -BIC_THRESHOLD:
            kinds = ", ".join(sorted({p.kind for p in joint.generics})) or "none"
            withdrawn[f.effect] = (f"withdrawn by the backward pass: in the joint model "
                                   f"(generic extensions: {kinds}) keeping it is worth only "
                                   f"ΔBIC {m[0]:.1f}; its signature does not match the data")
            joint.spec = m[2]
            joint.fit = joint_fit(ctx, joint.spec, joint.generics)
    for f in findings:
        if f.effect not in withdrawn:
            _annotate(ctx, joint, f)
    return withdrawn


def _annotate(ctx: Context, joint: Joint, finding: Finding) -> None:
    """Marginal evidence and joint-fit intervals of one kept finding."""
    m = _marginal(ctx, joint, finding.effect)
    if m is not None:
        finding.extra["marginal"] = {"delta_bic": m[0], "rmse_v_without": m[1],
                                     "rmse_v_with": held_out_rmse(joint.fit)}
    plugin = joint_parameters(ctx, joint.fit, finding.effect)
    if plugin is not None:  # a plugin effect reports its joint-fit parameters (shape kept)
        finding.parameters = {**finding.parameters, **plugin[0]}
        finding.ci95 = {**finding.ci95, **plugin[1]}
        finding.extra["joint_fit"] = {"parameters": plugin[0], "ci95": plugin[1]}
        return
    spec = _LINEAR_PARAMS.get(finding.effect)
    if spec is not None and spec[0] in joint.fit.names:
        column, key, per_scale = spec
        value, ci = linear_ci(ctx, joint.fit, column, divide_by_scale=per_scale)
        finding.extra["joint_fit"] = {"parameters": {key: value}, "ci95": {key: ci}}
        # the joint model (every accepted effect and generic extension) is the estimate: the
        # value at acceptance held the effects accepted later, or the unnamed structure, at 0
        finding.parameters = {**finding.parameters, key: value}
        finding.ci95 = {**finding.ci95, key: ci}
