"""Honest about what it cannot name: generic extensions on top of the named model.

After forward selection the residual is tested for remaining structure
(:mod:`aatest.diagnose.generic`). Each generic extension is fitted *jointly* with the named
model — its design columns appended to the named design, coefficients refitted on one fold
of time blocks and scored on the other — and accepted by the same rule as a named effect:
held-out ΔBIC below −:data:`~aatest.diagnose.selection.BIC_THRESHOLD` and a material drop of
the held-out RMS. What is accepted goes to ``unexplained`` (docs/interfaces.md §4).

Then the backward pass (:mod:`aatest.diagnose.refit`) re-tests every named effect in the
joint model: a vocabulary effect whose signature does not match (a scale-factor trend
absorbed by a cubic, a bias step absorbed by a temperature coefficient) loses its evidence
once the generic extension explains the structure, and is withdrawn with that reason.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from aatest.diagnose.candidates.base import Context
from aatest.diagnose.generic import Proposal, proposals
from aatest.diagnose.gram import Fit
from aatest.diagnose.joint import (
    Joint,
    _prune,
    bic_change,
    held_out_rmse,
    joint_fit,
    joint_residuals,
)
from aatest.diagnose.refit import backward_pass
from aatest.diagnose.selection import BIC_THRESHOLD, MIN_REDUCTION, Finding

#: generic extensions accepted per channel at most
MAX_UNEXPLAINED = 4
@dataclass
class Outcome:
    """What the generic pass found on one channel."""

    joint: Joint
    unexplained: list[dict[str, Any]]
    #: named effects withdrawn by the backward pass, with the reason
    withdrawn: dict[str, str]


def _best_addition(ctx: Context, joint: Joint) -> tuple[float, Proposal, Fit] | None:
    """The passing generic extension with the lowest held-out ΔBIC, if any."""
    taken = {p.key for p in joint.generics}
    residuals = joint_residuals(ctx, joint)
    best = None
    for prop in proposals(ctx.replay.steps, residuals, ctx.info.range_dps2):
        if prop.key in taken:
            continue
        fit = joint_fit(ctx, joint.spec, [*joint.generics, prop])
        dbic = bic_change(ctx, fit, joint.fit, prop.shape_params)
        material = held_out_rmse(fit) < (1.0 - MIN_REDUCTION) * held_out_rmse(joint.fit)
        if dbic < -BIC_THRESHOLD and material and (best is None or dbic < best[0]):
            best = (dbic, prop, fit)
        # only the taken extensions' and the best one's columns are needed again: a
        # proposal's columns on every step (up to a few MB each) are not kept past its trial
        _prune(ctx, joint.generics + ([best[1]] if best is not None else []))
    return best


def _entry(ctx: Context, joint: Joint, prop: Proposal, evidence: dict[str, float]
           ) -> dict[str, Any]:
    names = joint.fit.names
    coef = np.array([joint.fit.coef[j] for j, n in enumerate(names)
                     if n.startswith(f"{prop.key}#")])
    description, extension = prop.describe(coef, ctx.scale_of(joint.fit))
    return {"kind": prop.kind, "description": description, "evidence": evidence,
            "extension": extension, "channel": ctx.info.channel}


def explain(ctx: Context, named: Fit, findings: list[Finding]) -> Outcome:
    """Generic extensions on top of ``named``, then the backward pass over ``findings``.

    ``findings`` (this channel's named effects) gain their marginal evidence in place.
    """
    joint = Joint(named.spec, [], named)  # the same design and folds as joint_fit(…, [])
    while len(joint.generics) < MAX_UNEXPLAINED:
        best = _best_addition(ctx, joint)
        if best is None:
            break
        dbic, prop, fit = best
        joint.evidence.append({"delta_bic": dbic, "rmse_v_before": held_out_rmse(joint.fit),
                               "rmse_v_after": held_out_rmse(fit)})
        joint.generics.append(prop)
        joint.fit = fit
    withdrawn = backward_pass(ctx, joint, findings)
    entries = [_entry(ctx, joint, p, e)
               for p, e in zip(joint.generics, joint.evidence, strict=True)]
    return Outcome(joint, entries, withdrawn)
