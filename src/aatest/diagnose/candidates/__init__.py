"""The candidate effects of diagnose: one per contract effect (docs/interfaces.md §4 vocabulary).

``CANDIDATES`` maps each built-in effect to (testability check, fit, attribution). Effects
handled outside the residual fit — ``clock_drift`` (from the sync edges), ``excess_noise``
(from the residual spectrum), ``misalignment`` (the cross-axis fit read as a tilt) — live in
:mod:`aatest.diagnose.candidates.logger` and the selection. ``amplitude_damping`` extends
``sensor_dynamics`` and is tested only once the dynamics are accepted (``requires``).

The vocabulary is open: :func:`vocabulary` adds every installed effect plugin (entry-point
group ``aatest.effects``, :mod:`aatest.effects`) as a candidate of the same kind, replacing a
built-in only when the plugin declares ``shadows = True``
(:mod:`aatest.diagnose.candidates.plugins`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from aatest.diagnose.candidates import (
    amplitude,
    distortion,
    linear,
    plugins,
    shape,
    stiction,
    table,
    vibration,
)
from aatest.diagnose.candidates.base import CandidateFit, Context
from aatest.effects import installed_effects


@dataclass(frozen=True)
class Candidate:
    """One model extension: when it can be tested, how it is fitted, where it lives."""

    effect: str
    testable: Callable[[Context], str | None]
    fit: Callable[[Context], CandidateFit]
    attributed_to: str = "sensor"
    #: effects that change the timing of the output (fitted without the alignment nuisance)
    time_family: bool = False
    #: how many times the effect may be accepted (several ripple lines, e.g. 1 and 2 cycles/°)
    repeatable: int = 1
    #: nonlinear parameters the fit searches (counted by the BIC on top of the design columns)
    shape_params: int = 0
    #: the distribution that provides a plugin effect (None: built-in)
    distribution: str | None = None
    #: an effect this one extends: it waits (untested) until that one is accepted
    requires: str | None = None


def _lin(name: str) -> Callable[[Context], CandidateFit]:
    return lambda ctx: linear.fit_linear(ctx, name)


CANDIDATES: tuple[Candidate, ...] = (
    Candidate("bias_temperature", linear.testable_bias_temperature, _lin("bias_temperature")),
    Candidate("scale_temperature", linear.testable_scale_temperature, _lin("scale_temperature")),
    Candidate("nonlinearity_cubic", linear.testable_cubic, _lin("nonlinearity_cubic")),
    Candidate("saturation", shape.testable_dynamic, shape.fit_saturation),
    Candidate("hysteresis", shape.testable_dynamic, shape.fit_hysteresis),
    Candidate("sensor_dynamics", shape.testable_dynamics, shape.fit_dynamics, time_family=True),
    Candidate("amplitude_damping", amplitude.testable_amplitude,
              amplitude.fit_amplitude_damping, time_family=True, shape_params=1,
              requires="sensor_dynamics"),
    Candidate("time_delay", shape.testable_dynamic, shape.fit_delay, time_family=True),
    Candidate("jerk_sensitivity", shape.testable_dynamic, shape.fit_jerk, time_family=True),
    Candidate("g_sensitivity", linear.testable_gravity, _lin("g_sensitivity")),
    Candidate("cross_axis", linear.testable_cross, linear.fit_cross),
    Candidate("rate_ripple", table.testable_ripple, table.fit_ripple, attributed_to="table",
              repeatable=3),
    Candidate("motor_vibration", vibration.testable_vibration, vibration.fit_vibration,
              attributed_to="table"),
    Candidate("rotor_stiction", stiction.testable_stiction, stiction.fit_stiction,
              shape_params=1),
    Candidate("jerk_distortion", distortion.testable_distortion,
              distortion.fit_jerk_distortion),
)



def plugin_candidates() -> tuple[Candidate, ...]:
    """One candidate per installed effect plugin (validated on load; a broken one raises)."""
    return tuple(Candidate(name, plugins.testability(inst), plugins.fitter(inst),
                           attributed_to=inst.effect.attributed_to,
                           shape_params=len(inst.effect.shape_parameters),
                           distribution=inst.distribution)
                 for name, inst in sorted(installed_effects().items()))


def vocabulary() -> tuple[Candidate, ...]:
    """The candidates of a diagnosis: the built-ins, then the installed plugin effects.

    A plugin that shadows a built-in (declared, else loading fails) takes its place.
    """
    extra = plugin_candidates()
    shadowed = {c.effect for c in extra}
    return tuple(c for c in CANDIDATES if c.effect not in shadowed) + extra


__all__ = ["CANDIDATES", "Candidate", "CandidateFit", "Context", "plugin_candidates",
           "vocabulary"]
