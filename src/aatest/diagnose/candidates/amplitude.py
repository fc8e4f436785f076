"""``amplitude_damping``: the damping of the sensor dynamics follows the acceleration amplitude.

The fluid rotor damps small motions more (docs/method.md §1.3): ζ(A) = ζ + c·log10(A/A_ref).
It extends ``sensor_dynamics`` (there is no damping to vary without it), so it is a candidate
only once the dynamics are in the model (:attr:`Candidate.requires`). Its signature is the
dynamics' lag and droop changing *with amplitude at the same frequency*, which no fixed
second-order low-pass, delay or jerk term has; hysteresis also lags more at small amplitude,
but by r/A (a shift that vanishes at large amplitude, with odd harmonics), not through the
resonance (a lag growing with frequency).

The reference amplitude is a convention, not a fit: ζ and A_ref trade exactly, so diagnose
reports ``reference_dps2`` = :data:`REFERENCE_DPS2` (the twin's default) and
``sensor_dynamics.damping`` is then ζ at 10 °/s².
"""

from __future__ import annotations

import numpy as np

from aatest.diagnose.candidates.base import (
    CandidateFit,
    Context,
    curvature_ci,
    replace_spec,
    scalar_search,
)
from aatest.diagnose.candidates.shape import DAMPING_BOUNDS
from aatest.diagnose.design import MIN_AMPLITUDE_DPS2, step_amplitude_dps2
from aatest.diagnose.spec import Spec

#: the amplitude at which ``sensor_dynamics.damping`` holds (°/s²)
REFERENCE_DPS2 = 10.0
#: search bound of the damping change per decade of amplitude
MAX_PER_DECADE = 0.5
#: the dynamic steps' amplitudes must span this many decades (a factor of 2)
MIN_SPAN_DECADES = 0.3
#: sine steps (with motion along the sensor axis) needed to see a trend over amplitude
MIN_STEPS = 2
_SEEDS = [-0.5, -0.3, -0.2, -0.12, -0.06, 0.0, 0.06, 0.12, 0.2, 0.3, 0.5]


def _amplitudes(ctx: Context) -> np.ndarray:
    """Amplitude (°/s²) along the sensor axis of every sine step that carries one."""
    amps = [step_amplitude_dps2(s, ctx.info) for s in ctx.replay.steps if s.dynamic
            and (s.inner.frequency_hz or s.outer.frequency_hz)]
    return np.asarray([a for a in amps if a >= MIN_AMPLITUDE_DPS2])


def testable_amplitude(ctx: Context) -> str | None:
    amps = _amplitudes(ctx)
    if amps.size < MIN_STEPS or np.log10(amps.max() / amps.min()) < MIN_SPAN_DECADES:
        return "needs sine steps at accelerations a factor of two or more apart"
    return None


def _weighted_log_amplitude(ctx: Context) -> float:
    """log10 of the amplitude the fixed-ζ fit effectively describes: the steps' log
    amplitudes weighted by the squared amplitude (their weight in the residual)."""
    amps = _amplitudes(ctx)
    return float(np.sum(amps**2 * np.log10(amps)) / np.sum(amps**2))


def fit_amplitude_damping(ctx: Context) -> CandidateFit:
    """Damping change per decade, the dynamics' ζ re-centred on the reference amplitude.

    The accepted ζ is what one damping makes of all steps, i.e. ζ near the amplitude the
    residual weights most; for each trial c the reference damping is moved so that ζ stays
    there, and the joint refinement after acceptance re-fits fn, ζ and c together.
    """
    base = ctx.current.spec
    assert base.dynamics is not None
    fn, zeta = base.dynamics
    centre = _weighted_log_amplitude(ctx) - np.log10(REFERENCE_DPS2)

    def make(c: float) -> Spec:
        z_ref = float(np.clip(zeta - c * centre, *DAMPING_BOUNDS))
        return replace_spec(base, dynamics=(fn, round(z_ref, 9)),
                            amplitude_damping=(round(c, 9), REFERENCE_DPS2))

    c, fit = scalar_search(ctx, make, -MAX_PER_DECADE, MAX_PER_DECADE, _SEEDS, xtol=1e-4)
    ci = curvature_ci(ctx, make, c, 0.01 * max(abs(c), 0.01), lo=-MAX_PER_DECADE,
                      hi=MAX_PER_DECADE)
    return CandidateFit("amplitude_damping", fit,
                        {"damping_per_decade": c, "reference_dps2": REFERENCE_DPS2},
                        {"damping_per_decade": ci},
                        extra={"step_amplitudes_dps2": sorted(set(np.round(_amplitudes(ctx),
                                                                           3).tolist()))})
