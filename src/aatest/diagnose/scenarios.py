"""Twin datasets with hidden effects: the self-test of ``aatest diagnose``.

A *scenario* is a rig model with zero, one or two contract effects switched on (type and
magnitude drawn from a seeded generator) and a step plan in which every effect of the
vocabulary is testable: a temperature sweep, several frequencies and accelerations, static
orientations at ±1 g, outer-axis sines at inner 0° and 90° (cross-axis), constant-rate steps
(rate ripple). Tests and ``bench/diagnose.py`` export these through the import format and run
the CLI on them as a user would.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from aatest.engine.datasheet import REFERENCE_SCALE_V_PER_DPS2 as _K_V
from aatest.engine.steps import PlannedStep
from aatest.rig_defaults import LOG_RATE_HZ
from aatest.twin import model as m

FS_HZ = LOG_RATE_HZ


def _sine(sid: str, cycles: int, accel: float, samples: int, *, axis: str = "inner",
          inner: float = 0.0, temp: float | None = None) -> PlannedStep:
    f = cycles * FS_HZ / samples
    return PlannedStep(id=sid, kind="sine", axis=axis, samples=samples, sample_rate_hz=FS_HZ,
                       duration_s=samples / FS_HZ, frequency_hz=f, cycles=cycles,
                       accel_dps2=accel, amplitude_deg=accel / (2 * np.pi * f) ** 2,
                       inner_deg=inner, temperature_c=temp, soak_s=None if temp is None else 3600.0)


def _static(sid: str, outer: float, samples: int, temp: float | None = None) -> PlannedStep:
    return PlannedStep(id=sid, kind="static", axis="none", samples=samples, sample_rate_hz=FS_HZ,
                       duration_s=samples / FS_HZ, outer_deg=outer, temperature_c=temp,
                       soak_s=None if temp is None else 3600.0)


def _rate(sid: str, rate: float, samples: int) -> PlannedStep:
    return PlannedStep(id=sid, kind="constant_rate", axis="inner", samples=samples,
                       sample_rate_hz=FS_HZ, duration_s=samples / FS_HZ, rate_dps=rate)


def diagnostic_plan(samples: int = 2**14) -> list[PlannedStep]:
    """Twelve short steps that make every effect of the vocabulary testable.

    Cycle counts make every sine coherent (an integer number of periods per record).
    """
    c = samples / 16384.0
    return [
        _static("up-hot", 0.0, samples, temp=45.0),
        _static("down", 180.0, samples, temp=25.0),
        _sine("f1-a400-cold", int(8 * c), 400.0, samples, temp=5.0),
        _sine("f1-a400", int(8 * c), 400.0, samples, temp=25.0),
        _sine("f4-a100", int(33 * c), 100.0, samples),
        _sine("f8-a400", int(66 * c), 400.0, samples),
        _sine("f2-a20", int(16 * c), 20.0, samples),
        _sine("f6-a300-hot", int(49 * c), 300.0, samples, temp=45.0),
        _sine("outer-i0", int(8 * c), 100.0, samples, axis="outer", inner=0.0),
        _sine("outer-i90", int(8 * c), 100.0, samples, axis="outer", inner=90.0),
        _rate("rate30", 30.0, samples),
        _rate("rate50", 50.0, samples),
    ]


def clean_rig(seed: int = 0) -> m.RigModel:
    """A rig with no effect switched on (1 mV noise, 100 Hz pre-sample filter, one clock)."""
    sensor = m.SensorModel(channel="v_sz", axis="I", bias_v=2.5 + 0.002 * (seed % 5),
                           noise_rms_v=0.001)
    return m.RigModel(sensors=[sensor])


@dataclass(frozen=True)
class Hidden:
    """One hidden effect: its contract name, parameters and the key parameter to check."""

    effect: str
    parameters: dict[str, float]
    check: tuple[str, ...]
    extra: dict[str, Any] = field(default_factory=dict)


def _u(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(rng.uniform(lo, hi))


def _signed(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(rng.choice([-1.0, 1.0]) * rng.uniform(lo, hi))


#: effect → draw(rng) of a magnitude well inside what the plan can reveal
DRAWS: dict[str, Callable[[np.random.Generator], Hidden]] = {
    "bias_temperature": lambda r: Hidden(
        "bias_temperature", {"coefficient_v_per_c": _signed(r, 1e-4, 5e-4)},
        ("coefficient_v_per_c",)),
    "scale_temperature": lambda r: Hidden(
        "scale_temperature", {"coefficient_per_c": _signed(r, 2e-4, 1e-3)},
        ("coefficient_per_c",)),
    "nonlinearity_cubic": lambda r: Hidden(
        "nonlinearity_cubic", {"c3": _signed(r, 0.01, 0.05)}, ("c3",)),
    "saturation": lambda r: Hidden(
        "saturation", {"limit_dps2": _u(r, 250.0, 360.0)}, ("limit_dps2",)),
    "hysteresis": lambda r: Hidden(
        "hysteresis", {"half_width_dps2": _u(r, 1.0, 4.0)}, ("half_width_dps2",)),
    "sensor_dynamics": lambda r: Hidden(
        "sensor_dynamics", {"natural_frequency_hz": _u(r, 15.0, 40.0), "damping": _u(r, 0.4, 0.8)},
        ("natural_frequency_hz", "damping")),
    "time_delay": lambda r: Hidden("time_delay", {"delay_s": _u(r, 0.002, 0.015)}, ("delay_s",)),
    "clock_drift": lambda r: Hidden(
        "clock_drift", {"drift_ppm": _signed(r, 60.0, 200.0)}, ("drift_ppm",)),
    "jerk_sensitivity": lambda r: Hidden(
        "jerk_sensitivity", {"coefficient_v_per_dps3": _K_V * _u(r, 1.5e-3, 5e-3)},
        ("coefficient_v_per_dps3",)),
    "g_sensitivity": lambda r: Hidden(
        "g_sensitivity", {"coefficient_dps2_per_g": _signed(r, 0.5, 2.0)},
        ("coefficient_dps2_per_g",)),
    "cross_axis": lambda r: Hidden(
        "cross_axis", {"ratio_x": _signed(r, 0.004, 0.015), "ratio_y": _signed(r, 0.004, 0.015)},
        ("ratio_x", "ratio_y")),
    "misalignment": lambda r: Hidden(
        "misalignment", {"angle_deg": _u(r, 0.3, 1.0)}, ("angle_deg",),
        {"azimuth_deg": _u(r, 0.0, 360.0)}),
    "rate_ripple": lambda r: Hidden(
        "rate_ripple", {"cycles_per_deg": float(r.choice([1.0, 2.0])),
                        "amplitude_deg": _u(r, 0.5, 2.0) / 3600},
        ("cycles_per_deg", "amplitude_deg")),
    "motor_vibration": lambda r: Hidden(
        "motor_vibration", {"frequency_hz": _u(r, 25.0, 45.0), "amplitude_dps2": _u(r, 2.0, 8.0)},
        ("frequency_hz", "amplitude_dps2"),
        {"bandwidth_hz": float(r.choice([0.0, _u(r, 2.0, 6.0)]))}),
    "excess_noise": lambda r: Hidden("excess_noise", {"rms_v": _u(r, 0.002, 0.012)}, ("rms_v",)),
    # 2nd harmonic 1.5–5 % in the 8 Hz, 400 °/s² step (the realistic default: 2.7 %)
    "jerk_distortion": lambda r: Hidden(
        "jerk_distortion", {"coefficient_v_per_dps3_squared": _K_V * _u(r, 3e-8, 1e-7)},
        ("coefficient_v_per_dps3_squared",)),
}


def draw_amplitude_damping(seed: int) -> list[Hidden]:
    """Sensor dynamics whose damping follows the amplitude (seeded): both effects hidden,
    since ``amplitude_damping`` varies the damping of ``sensor_dynamics`` and means nothing
    without it. ``damping`` is ζ at the 10 °/s² reference diagnose reports it at."""
    r = np.random.default_rng([seed, len("amplitude_damping")])
    return [Hidden("sensor_dynamics", {"natural_frequency_hz": _u(r, 20.0, 40.0),
                                       "damping": _u(r, 0.5, 0.9)},
                   ("natural_frequency_hz", "damping")),
            Hidden("amplitude_damping", {"damping_per_decade": _signed(r, 0.08, 0.2)},
                   ("damping_per_decade",), {"reference_dps2": 10.0})]


def draw_rotor_stiction(seed: int) -> Hidden:
    """A rotor stiction gap (seeded) the diagnostic plan's slowest sines reveal: break-away
    rate 0.3–0.8 °/s against their 1.6–8 °/s rate amplitudes, depth 0.3–0.6. Not in
    :data:`DRAWS`: the suites keep their cases (its own tests hide it)."""
    r = np.random.default_rng([seed, len("rotor_stiction")])
    return Hidden("rotor_stiction", {"breakaway_rate_dps": _u(r, 0.3, 0.8),
                                     "depth": _u(r, 0.3, 0.6)}, ("breakaway_rate_dps", "depth"))


def draw_hidden(effect: str, seed: int) -> Hidden:
    """A hidden effect of type ``effect`` with a seeded random magnitude."""
    return DRAWS[effect](np.random.default_rng([seed, len(effect)]))


def with_effects(rig: m.RigModel, hidden: list[Hidden]) -> m.RigModel:
    """The rig with the hidden effects switched on (sensor, table or logger side)."""
    sensor = rig.sensors[0]
    table, daq = rig.table, rig.daq
    for h in hidden:
        params = {**h.parameters, **h.extra}
        if h.effect == "clock_drift":
            daq = daq.model_copy(update={"clock_drift": m.ClockDrift(**params)})
        elif h.effect == "rate_ripple":
            table = table.model_copy(update={"inner": table.inner.model_copy(
                update={"rate_ripple": [m.RateRipple(**params, phase_rad=0.7)]})})
        elif h.effect == "motor_vibration":
            table = table.model_copy(update={"inner": table.inner.model_copy(
                update={"motor_vibration": m.MotorVibration(**params, phase_rad=0.3)})})
        else:
            sensor = sensor.model_copy(update={h.effect: m.EFFECTS[h.effect](**params)})
    return rig.model_copy(update={"sensors": [sensor], "table": table, "daq": daq})


def scenario_dataset(hidden: list[Hidden], seed: int, samples: int = 2**14) -> Any:
    """Simulate the diagnostic plan on a rig with ``hidden`` effects (a Dataset)."""
    from aatest.twin.api import simulate_dataset

    rig = with_effects(clean_rig(seed), hidden)
    return simulate_dataset(rig, diagnostic_plan(samples), seed, procedure="diagnose-scenario")


def without_latch(dataset: Any) -> Any:
    """The same data as a rig that does not log ``fp_latch_s`` would have recorded it.

    The table then only shows at which sample it registered each edge, so the sync resolves
    the logger alignment to one sample (docs/interfaces.md §4).
    """
    from dataclasses import replace as dc_replace

    steps = tuple(dc_replace(s, table=dc_replace(
        s.table, channels={k: v for k, v in s.table.channels.items() if k != "fp_latch_s"},
        units={k: v for k, v in s.table.units.items() if k != "fp_latch_s"}))
        for s in dataset.steps)
    return dc_replace(dataset, steps=steps,
                      metadata={**dataset.metadata, "fp_latch_s_present": False})


#: hidden effect → finding names that count as naming it (one-mounting look-alikes)
ACCEPTED_NAMES = {"misalignment": ("misalignment", "cross_axis"),
                  "cross_axis": ("cross_axis", "misalignment")}
TOLERANCE = 0.25
#: smallest held-out RMS reduction that counts as a real gain (%)
MIN_GAIN_PCT = 5.0


def _finding_value(finding: dict[str, Any], hidden: Hidden, key: str) -> float | None:
    if finding["effect"] == hidden.effect:
        return finding["parameters"].get(key)
    if hidden.effect == "misalignment" and finding["effect"] == "cross_axis":
        return finding.get("look_alike", {}).get("parameters", {}).get(key)
    if hidden.effect == "cross_axis" and finding["effect"] == "misalignment":
        return None
    return None


def judge(doc: dict[str, Any], hidden: list[Hidden]) -> list[str]:
    """Problems with a diagnosis of data with ``hidden`` effects (empty list = correct).

    Correct means: every hidden effect named (look-alikes per :data:`ACCEPTED_NAMES`), its
    checked parameters within 25 %, a real gain, and nothing else found.
    """
    problems: list[str] = []
    findings = doc["findings"]
    if not hidden:
        return [f"false positive: {f['effect']}" for f in findings]
    named = set()
    for h in hidden:
        match = [f for f in findings if f["effect"] in ACCEPTED_NAMES.get(h.effect, (h.effect,))]
        if not match:
            problems.append(f"{h.effect} not found")
            continue
        named.add(match[0]["effect"])
        for key in h.check:
            est, true = _finding_value(match[0], h, key), h.parameters[key]
            if est is None or abs(est - true) > TOLERANCE * abs(true):
                problems.append(f"{h.effect}.{key} = {est!r}, truth {true:.6g}")
    extra = [f["effect"] for f in findings if f["effect"] not in named]
    problems += [f"extra finding: {e}" for e in extra]
    gain = doc["gain"]["reduction_pct"]
    noise_only = all(h.effect == "excess_noise" for h in hidden)
    if not noise_only and gain < MIN_GAIN_PCT:
        problems.append(f"gain only {gain:.1f} %")
    return problems


#: pairs of hidden effects for the suite (each pair must be found together)
PAIRS: tuple[tuple[str, str], ...] = (
    ("bias_temperature", "time_delay"), ("cross_axis", "saturation"),
    ("rate_ripple", "scale_temperature"), ("motor_vibration", "g_sensitivity"),
    ("sensor_dynamics", "bias_temperature"), ("hysteresis", "clock_drift"),
)


def suite_cases(seeds: tuple[int, ...] = (1, 2), clean: int = 5
                ) -> list[tuple[str, list[Hidden], int]]:
    """The full hidden-effect suite: every effect per seed, clean rigs, and the pairs."""
    cases = [(f"{e}-s{s}", [draw_hidden(e, s)], s) for s in seeds for e in DRAWS]
    cases += [(f"clean-s{s}", [], 100 + s) for s in range(clean)]
    cases += [(f"{a}+{b}", [draw_hidden(a, 7), draw_hidden(b, 8)], 7) for a, b in PAIRS]
    return cases
