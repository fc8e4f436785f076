"""The data requirements of the built-in analyses (:mod:`aatest.engine.requirements`).

Each analysis class names its tuple here as ``requirements``; ``aatest validate`` checks them
against the plan before anything moves, and docs/interfaces.md lists them (generated from
these declarations, checked by a test).
"""

from __future__ import annotations

import numpy as np

from aatest.clocksync.streamed import MIN_RATE_OVER_PULSE
from aatest.engine.requirements import Check, PlanView, Requirement, steps_where
from aatest.engine.steps import PlannedStep
from aatest.plugins.analysis.geometry import gravity_along_g, nominal_weight

#: the highest frequency a scale-factor step may have, Hz (docs/method.md §4.3)
MAX_CAL_FREQUENCY_HZ = 2.0
#: set-points a temperature coefficient needs, and the span they must cover (°C)
MIN_SETPOINTS, MIN_SPAN_C = 3, 5.0
#: |nominal weight| above which a step excites a sensor axis (as the analyses use it)
EXCITED = 0.5
#: a static position counts as "axis up/down" above this |g| component (as the bias)
UP_G = 0.9


def _per_axis(need: str, picks: dict[str, list[PlannedStep]], view: PlanView) -> Check:
    """Met when every sensor channel has at least one step in ``picks``."""
    used = tuple(dict.fromkeys(s.id for steps in picks.values() for s in steps))
    missing = [ch for ch in view.sensor_axes if not picks.get(ch)]
    if missing:
        return Check(used, f"needs {need}; none for channel(s) {', '.join(missing)}")
    return Check(used)


def _bias_pairs(view: PlanView) -> Check:
    static = view.recorded("static")
    picks: dict[str, list[PlannedStep]] = {}
    for channel, axis in view.sensor_axes.items():
        g = [(s, gravity_along_g(axis, s.inner_deg, s.outer_deg)) for s in static]
        up = [s for s, x in g if x >= UP_G]
        down = [s for s, x in g if x <= -UP_G]
        picks[channel] = up + down if up and down else []
    return _per_axis(BIAS_NEED, picks, view)


BIAS_NEED = ("static positions with each sensor's axis up and down (a ±1 g pair: a g "
             f"component ≥ +{UP_G} and one ≤ −{UP_G})")


def _scale_steps(view: PlanView) -> Check:
    picks = {ch: [s for s in view.recorded("sine")
                  if abs(nominal_weight(s, axis)) >= EXCITED
                  and (s.frequency_hz or 0.0) <= MAX_CAL_FREQUENCY_HZ]
             for ch, axis in view.sensor_axes.items()}
    return _per_axis(SCALE_NEED, picks, view)


SCALE_NEED = (f"sine steps along each sensor's axis at ≤ {MAX_CAL_FREQUENCY_HZ:g} Hz (every "
              "acceleration level at the frequency nearest 1 Hz is analysed)")


def _setpoints(view: PlanView) -> Check:
    return _spanned(SETPOINT_NEED, [s for s in view.recorded() if s.temperature_c is not None])


SETPOINT_NEED = (f"records at ≥ {MIN_SETPOINTS} chamber set-points spanning ≥ {MIN_SPAN_C:g} °C "
                 "(static steps for the bias coefficient, sine steps for the scale coefficient)")


def _spanned(need: str, steps: list[PlannedStep]) -> Check:
    """Met when ``steps`` lie at ≥ MIN_SETPOINTS set-points spanning ≥ MIN_SPAN_C."""
    temps = sorted({float(s.temperature_c) for s in steps if s.temperature_c is not None})
    used = tuple(s.id for s in steps)
    if len(temps) < MIN_SETPOINTS or temps[-1] - temps[0] < MIN_SPAN_C:
        return Check(used, f"needs {need}; the plan has "
                     f"{', '.join(f'{t:g} °C' for t in temps) or 'none'}")
    return Check(used)


def _static_setpoints(view: PlanView) -> Check:
    return _spanned(STATIC_SETPOINT_NEED, view.recorded("static"))


def _sine_setpoints(view: PlanView) -> Check:
    """The sine steps of the (frequency, acceleration) point planned at the most set-points:
    the scale coefficient compares one point's gain across temperatures."""
    sine = [s for s in view.recorded("sine") if s.temperature_c is not None]
    points: dict[tuple[float, float | None], list[PlannedStep]] = {}
    for s in sine:
        points.setdefault((round(float(s.frequency_hz or 0.0), 6), s.accel_dps2), []).append(s)
    best = max(points.values(), key=lambda p: len({s.temperature_c for s in p}), default=[])
    return _spanned(SINE_SETPOINT_NEED, best)


STATIC_SETPOINT_NEED = (f"static records at ≥ {MIN_SETPOINTS} chamber set-points spanning "
                        f"≥ {MIN_SPAN_C:g} °C")
SINE_SETPOINT_NEED = (f"sine records of one frequency and acceleration at ≥ {MIN_SETPOINTS} "
                      f"chamber set-points spanning ≥ {MIN_SPAN_C:g} °C")
#: what the plan must hold for each temperature coefficient (``produces``)
TEMPERATURE_PRODUCES = {
    "bias_temperature_v_per_c": Requirement(STATIC_SETPOINT_NEED, _static_setpoints),
    "scale_temperature_per_c": Requirement(SINE_SETPOINT_NEED, _sine_setpoints),
}


def _chamber(view: PlanView) -> Check:
    first = next((s for s in view.steps if s.temperature_c is not None), None)
    if first is not None and view.chamber == "none":
        return Check((), "needs a chamber plugin in the rig (rig.chamber) for its set-points; "
                     "the rig has none", first.id)
    return Check()


def _three_sensors(view: PlanView) -> Check:
    axes = set(view.sensor_axes.values())
    if not axes >= {"I", "O", "P"}:
        return Check((), f"needs {THREE_NEED}; the sensor has axes "
                     f"{', '.join(sorted(axes)) or 'none'} (a single-axis sensor's cross-axis "
                     "sensitivity is measured by the analysis 'cross_axis')")
    return Check()


THREE_NEED = "a three-sensor unit (sensors on the I, O and P axes)"

#: least angle between two inner-axis positions of the cross-axis steps (their transverse
#: directions), ° — 45° keeps the 2×2 solve's condition number ≤ 2.4 (90° gives 1)
CROSS_MIN_SEPARATION_DEG = 45.0


def cross_axis_positions(steps: list[PlannedStep]) -> list[float]:
    """Distinct inner-axis positions (mod 180°) of outer-axis sine steps."""
    return sorted({round(s.inner_deg % 180.0, 6) for s in steps})


def _cross_steps(view: PlanView) -> Check:
    on_inner = [ch for ch, axis in view.sensor_axes.items() if axis == "I"]
    steps = [s for s in view.recorded("sine") if s.axis == "outer"]
    used = tuple(s.id for s in steps)
    if view.sensor_axes and not on_inner:
        return Check(used, f"needs {CROSS_NEED}; the sensor has no channel on the inner axis")
    positions = cross_axis_positions(steps)
    separated = any(
        abs(np.sin(np.deg2rad(b - a))) >= np.sin(np.deg2rad(CROSS_MIN_SEPARATION_DEG)) - 1e-12
        for i, a in enumerate(positions) for b in positions[i + 1:])
    if not separated:
        found = ", ".join(f"{p:g}°" for p in positions) or "none"
        return Check(used, f"needs {CROSS_NEED}; the plan's outer-axis sine steps are at inner "
                     f"{found}")
    return Check(used)


CROSS_NEED = ("outer-axis sine steps at two or more inner-axis positions at least "
              f"{CROSS_MIN_SEPARATION_DEG:g}° apart (e.g. 0° and 90°), for a sensor on the inner "
              "axis")

#: the freeze pulse of the documented rig, Hz: the DAQ's sync pulse (docs/method.md §2)
FREEZE_PULSE_HZ = 100.0
PULSE_NEED = (f"every recorded step logged at ≥ {MIN_RATE_OVER_PULSE * FREEZE_PULSE_HZ:g} Hz "
              f"(the {FREEZE_PULSE_HZ:g} Hz freeze pulse's edges resolved)")


def _resolves_pulse(view: PlanView) -> Check:
    """Every recorded step logged fast enough to hold both levels of the freeze pulse: at
    half that rate a log holds no edge at all, and sync would fail after the recording as if
    the pulse were not wired."""
    steps = view.recorded()
    slow = [s for s in steps if s.sample_rate_hz < MIN_RATE_OVER_PULSE * FREEZE_PULSE_HZ]
    if not slow:
        return Check(tuple(s.id for s in steps))
    more = f" (and {len(slow) - 1} more)" if len(slow) > 1 else ""
    return Check(tuple(s.id for s in steps),
                 f"needs {PULSE_NEED}; step {slow[0].id} is logged at "
                 f"{slow[0].sample_rate_hz:g} Hz{more}", slow[0].id)


SYNC = (steps_where("a recorded step", lambda s: True), Requirement(PULSE_NEED, _resolves_pulse))
BIAS = (Requirement(BIAS_NEED, _bias_pairs),)
SCALE_FACTOR = (Requirement(SCALE_NEED, _scale_steps),)
TEMPERATURE = (Requirement(SETPOINT_NEED, _setpoints),
               Requirement("a chamber plugin in the rig (rig.chamber)", _chamber))
MISALIGNMENT = (Requirement(THREE_NEED, _three_sensors),
                steps_where("sine steps of a misalignment scenario (the misalignment generator)",
                            lambda s: bool(s.mounting.scenario), kind="sine"))
STATIC = (steps_where("a static step", lambda s: True, kind="static"),)
SINE = (steps_where("a sine step", lambda s: True, kind="sine"),)
CROSS_AXIS = (Requirement(CROSS_NEED, _cross_steps),)


def sine_points(minimum: int) -> tuple[Requirement, ...]:
    """At least ``minimum`` sine steps (a transfer-function fit's frequency points)."""
    return (steps_where(f"at least {minimum} sine steps", lambda s: True, minimum, "sine"),)
