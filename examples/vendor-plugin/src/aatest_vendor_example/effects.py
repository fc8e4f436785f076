"""An asymmetric scale factor: what a lab writes to add its own effect to ``aatest diagnose``.

Some angular accelerometers are more sensitive to one sense of rotation than to the other
(a proof mass whose restoring spring is stiffer one way). The built-in vocabulary has no name
for that, so ``diagnose`` without this plugin reports it as ``unexplained`` (kind ``asymmetry``);
with it installed, the effect is a candidate like any built-in one, found with its parameter
and written by ``--model-out`` so that the twin simulates it.

Model (enters as an acceleration, i.e. before the scale factor K)::

    α_out = α·(1 + a/2) for α > 0,  α·(1 − a/2) for α < 0   ⇔   α_out = α + a·|α|/2

so K₊/K₋ = (1 + a/2)/(1 − a/2) and ``asymmetry`` a = (K₊ − K₋)/K (dimensionless). The term
is linear in ``a``: its one design column is |α|/2. Its signature is an *even* response
proportional to |α| — the part of the output that does not change sign with α — which a cubic
(odd in α) cannot produce and an even-order square law (∝ α²) grows differently with
amplitude; the selection weighs those on held-out data. It needs dynamic steps with a
reasonable share of the range.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from aatest.effects import Effect, EffectInputs, EffectParameter, Excitation

#: the effect needs sine steps reaching this share of the range to be told from noise
MIN_RANGE_FRACTION = 0.1
#: an asymmetry this large is a broken sensor, not a scale-factor effect
MAX_ASYMMETRY = 0.5


class AsymmetricScale(Effect):
    """Different scale factor for α > 0 and α < 0: α_out = α + a·|α|/2."""

    name = "asymmetric_scale"
    summary = "scale factor differs for positive and negative acceleration (K+ ≠ K−)"
    parameters = (EffectParameter("asymmetry", "1", "(K+ − K−)/K: relative difference of the "
                                  "scale factors for α > 0 and α < 0"),)
    enters = "acceleration"

    def columns(self, inputs: EffectInputs, shape: Mapping[str, float]) -> dict[str, np.ndarray]:
        """|α|/2 (°/s² per unit asymmetry)."""
        return {"asymmetry": 0.5 * np.abs(inputs.alpha_dps2)}

    def testable(self, excitation: Excitation) -> str | None:
        """Needs sine steps reaching at least 10 % of the range."""
        frac = excitation.peak_alpha_dps2 / excitation.range_dps2
        if frac < MIN_RANGE_FRACTION:
            return (f"peak acceleration is {100 * frac:.0f} % of range "
                    f"(< {100 * MIN_RANGE_FRACTION:.0f} %)")
        return None

    def signature(self, parameters: Mapping[str, float],
                  ci95: Mapping[str, list[float]]) -> str | None:
        """A real asymmetry is resolved from zero and physically small (|a| < 0.5)."""
        lo, hi = ci95["asymmetry"]
        if lo <= 0.0 <= hi:
            return "the asymmetry's 95 % interval includes zero"
        if abs(parameters["asymmetry"]) >= MAX_ASYMMETRY:
            return "an asymmetry of 50 % or more is a broken sensor, not a scale-factor effect"
        return None
