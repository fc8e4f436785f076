"""Which effects a diagnose model has, and what it needs about a sensor channel.

The two records every stage of diagnose passes around: a :class:`Spec` names the effects
switched on with the current values of their shape parameters, a :class:`ChannelInfo` the
channel's axis, range, logger filter and reference temperature. Kept apart from the design
matrix (:mod:`aatest.diagnose.design`) so the linear algebra (:mod:`aatest.diagnose.gram`)
and the candidates can use them without importing the model's columns.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from aatest.engine.datasheet import REFERENCE_SCALE_V_PER_DPS2


@dataclass(frozen=True)
class Spec:
    """Which effects a model has, with the current values of its shape parameters."""

    linear: frozenset[str] = frozenset()
    delay_s: float = 0.0
    dynamics: tuple[float, float] | None = None
    hysteresis_dps2: float = 0.0
    saturation_dps2: float | None = None
    ripple_cpd: tuple[float, ...] = ()
    #: the table log's ripple lines, (cycles/°, sin, cos coefficient °) on the ripple
    #: regressors: real motion, so the sensing element feels it with the commanded motion
    #: (a cubic, clipping or backlash acts on the sum, the jerk pickup on its derivative)
    ripple_motion_deg: tuple[tuple[float, float, float], ...] = ()
    vibration_hz: tuple[float, ...] = ()
    warp_ppm: float = 0.0
    #: warp about the record start (trigger-aligned loggers) instead of its middle (edge fit)
    warp_from_start: bool = False
    #: per-step alignment offsets (s) on top of ``delay_s``, indexed by step (empty = none):
    #: the sync pulse aligns each step's loggers to about one sample only
    step_shift_s: tuple[float, ...] = ()
    #: shape-parameter values of plugin effects (aatest.effects) in ``linear``:
    #: ((effect, ((parameter, value), …)), …)
    plugin_shape: tuple[tuple[str, tuple[tuple[str, float], ...]], ...] = ()
    #: ``amplitude_damping`` (damping_per_decade, reference_dps2): the damping of
    #: ``dynamics`` (ζ at the reference amplitude) follows each step's amplitude
    amplitude_damping: tuple[float, float] | None = None
    #: ``rotor_stiction``'s break-away rate (°/s; 0 = off): with ``rotor_stiction`` in
    #: ``linear`` a column of the response lost while the case's rate is within ±it of zero
    stiction_dps: float = 0.0

    def shift_of(self, index: int) -> float:
        """Total time shift of the prediction for step ``index`` (s)."""
        return self.delay_s + (self.step_shift_s[index] if self.step_shift_s else 0.0)

    def with_linear(self, *names: str) -> Spec:
        return replace(self, linear=self.linear | frozenset(names))


@dataclass(frozen=True)
class ChannelInfo:
    """What the design needs about one sensor channel."""

    channel: str
    axis: str
    range_dps2: float
    antialias_hz: float | None
    t_ref_c: float
    #: datasheet scale factor, used when the data cannot calibrate K (no motion along z)
    nominal_scale_v_per_dps2: float = REFERENCE_SCALE_V_PER_DPS2
