"""Step generators: one function per step kind of the procedure YAML, named like the key.

Each ``kind(walker, body, path)`` appends drafts of planned steps through the planner's walker
(``walker.emit``), in the order the rig will run them; ``path`` is the YAML path of the entry
so every step can be traced back to its line. The numerics live here too: coherent snapping
(f = c·Fs/N, c = round(f·N/Fs), halves up) and the sine relations A = α/(2πf)², α = A·(2πf)².

Example
-------
>>> snap_frequency(1.0, 2000.0, 131072)
(1.007080078125, 66)
>>> sine_motion(1.0, None, accel_dps2=400.0)["amplitude_deg"]  # doctest: +ELLIPSIS
10.132118...
"""

from __future__ import annotations

import math
from typing import Any, Protocol

import numpy as np

from aatest.engine.errors import ProcedureError
from aatest.engine.procedure.expansion import SkippedPoint, YamlPath
from aatest.engine.procedure.models import (
    MAX_COUNT,
    ConstantRate,
    CoordinatedRates,
    Misalignment,
    MultiPosition,
    Operator,
    Overrides,
    Procedure,
    Repeat,
    SineStep,
    SineSweep,
    StaticStep,
    StepEntry,
    SweepFrequencies,
    TemperatureSteps,
)
from aatest.engine.steps import Mounting


class Walker(Protocol):
    """What a generator uses of the planner's walker (``planner._Walker``): its state and the
    calls that append drafts. The planner calls the generators, so they name it by this
    protocol instead of importing it back."""

    proc: Procedure
    skipped: list[SkippedPoint]
    prompt: str | None
    temperature_c: float | None
    repetition: int
    rep_suffix: str

    def fail(self, path: YamlPath, message: str) -> ProcedureError:
        """The procedure error located at ``path``."""
        ...

    def record(self, ov: Overrides, settle_s: float | None = None) -> dict[str, Any]:
        """Sampling fields of a record, with the entry's overrides applied (``settle_s``, in
        s, replaces the entry's settling time)."""
        ...

    def snap(self, freq_hz: float, mode: str, rec: dict[str, Any]) -> tuple[float, int | None]:
        """``freq_hz`` (Hz) snapped to whole cycles of the record ``rec`` (``mode`` none:
        unchanged): the planned frequency in Hz and the cycle count (dimensionless; None when
        not snapped)."""
        ...

    def emit(self, label: str, source: YamlPath, prompt: str | None = None, **fields: Any) -> None:
        """Append the draft of one planned step."""
        ...

    def emit_or_skip(self, label: str, source: YamlPath, skip: bool, **fields: Any) -> bool:
        """Append a sweep point, or drop it when allowed and outside the envelope."""
        ...

    def walk(self, entries: tuple[StepEntry, ...], base: YamlPath) -> None:
        """Expand nested step entries in order."""
        ...


#: misalignment set → the re-mounting done before every repetition (docs/method.md §4.5)
REMOUNT = {"A": "none", "B": "none", "C": "sensors", "D": "sensors", "E": "block", "F": "block",
           "G": "both", "H": "both"}
_REMOUNT_TEXT = {"sensors": "the sensors on the block", "block": "the mounting block",
                 "both": "the sensors on the block and the block on the table"}
#: experiments 1–3 run in the original mounting, 4–6 with every sensor pivoted 180°
FIRST_PIVOTED_EXPERIMENT = 4


def snap_frequency(freq_hz: float, rate_hz: float, samples: int) -> tuple[float, int]:
    """Nearest coherent frequency: (c·Fs/N, c) with c = round(f·N/Fs) (halves up), c ≥ 1.

    ``freq_hz`` and the returned frequency are in Hz, ``rate_hz`` (the sample rate Fs) in Hz;
    ``samples`` (N) and the cycle count c are dimensionless counts.
    """
    cycles = max(1, math.floor(freq_hz * samples / rate_hz + 0.5))
    return cycles * rate_hz / samples, cycles


def sweep_points(freqs: SweepFrequencies, rate_hz: float,
                 samples: int) -> list[tuple[float, int | None]]:
    """(frequency_hz, cycles) of a sweep grid, ascending and without duplicates.

    Frequencies in Hz at the sample rate ``rate_hz`` (Hz); cycles per record, dimensionless.

    Explicit ``cycles`` define the grid; otherwise start·ratio^k ≤ stop, stop itself and
    ``include``, each snapped with :func:`snap_frequency` unless ``snap: none``.
    """
    if freqs.cycles is not None:
        return [(c * rate_hz / samples, c) for c in sorted(set(freqs.cycles))]
    nominal = [float(f) for f in freqs.include]
    if freqs.start_hz is not None and freqs.ratio is not None and freqs.stop_hz is not None:
        count = math.floor(math.log(freqs.stop_hz / freqs.start_hz) / math.log(freqs.ratio) + 1e-9)
        if count >= MAX_COUNT:
            raise ValueError(f"the geometric grid has {count + 1} points (at most {MAX_COUNT})")
        grid = freqs.start_hz * freqs.ratio ** np.arange(count + 1)
        nominal += [float(f) for f in grid] + [freqs.stop_hz]
    if freqs.snap == "none":
        return [(f, None) for f in sorted(set(nominal))]
    cycles = sorted({snap_frequency(f, rate_hz, samples)[1] for f in nominal})
    return [(c * rate_hz / samples, c) for c in cycles]


def num(value: float) -> str:
    """A number for a step id: shortest form, minus as ``m`` (−21 °C → ``m21``)."""
    return f"{value:g}".replace("-", "m")


def sine_motion(freq_hz: float, cycles: int | None, *, accel_dps2: float | None = None,
                amplitude_deg: float | None = None) -> dict[str, Any]:
    """Sine fields for a peak acceleration (A = α/ω²) or a position amplitude (α = A·ω²).

    ``freq_hz`` in Hz, ``accel_dps2`` (α) in °/s², ``amplitude_deg`` (A) in °; exactly one of
    the last two is given, the other is derived.
    """
    omega2 = (2.0 * math.pi * freq_hz) ** 2
    if accel_dps2 is not None:
        amplitude_deg, group = accel_dps2 / omega2, f"accel-{num(accel_dps2)}"
    elif amplitude_deg is not None:
        accel_dps2, group = amplitude_deg * omega2, f"position-{num(amplitude_deg)}deg"
    else:
        raise ValueError("a sine needs accel_dps2 or amplitude_deg")
    return {"kind": "sine", "frequency_hz": freq_hz, "cycles": cycles,
            "amplitude_deg": amplitude_deg, "accel_dps2": accel_dps2, "group": group}


def _sine_label(axis: str, motion: dict[str, Any], by_amplitude: bool) -> str:
    size = (f"{num(motion['amplitude_deg'])}deg" if by_amplitude
            else f"{num(motion['accel_dps2'])}dps2")
    return f"sine-{axis}-{motion['frequency_hz']:.4f}Hz-{size}"


# --- one function per step kind ---------------------------------------------------------------


def static(w: Walker, body: StaticStep, path: YamlPath) -> None:
    """Emit one static step at the given table position."""
    label = f"static-i{num(body.inner_deg)}-o{num(body.outer_deg)}"
    label = f"static-{body.label}" if body.label else label
    w.emit(label, path, kind="static", inner_deg=body.inner_deg, outer_deg=body.outer_deg,
           motor_on=body.motor_on, group="static", **w.record(body))


def sine(w: Walker, body: SineStep, path: YamlPath) -> None:
    """Emit one sine step, its frequency snapped to a whole number of cycles per record."""
    rec = w.record(body)
    cycles: int | None
    if body.cycles is not None:
        freq_hz, cycles = body.cycles * rec["sample_rate_hz"] / rec["samples"], body.cycles
    else:
        freq_hz, cycles = w.snap(float(body.frequency_hz or 0.0), body.snap, rec)
    motion = sine_motion(freq_hz, cycles, accel_dps2=body.accel_dps2,
                         amplitude_deg=body.amplitude_deg)
    w.emit(_sine_label(body.axis, motion, body.amplitude_deg is not None), path, axis=body.axis,
           inner_deg=body.inner_deg, outer_deg=body.outer_deg, **motion, **rec)


def sine_sweep(w: Walker, body: SineSweep, path: YamlPath) -> None:
    """Constant-position groups first, then constant-acceleration groups, each ascending in f.

    With ``skip_outside_envelope`` a point outside the envelope is dropped (and listed); a group
    whose every point is outside is an error located at its list element, never a silent gap.
    """
    rec = w.record(body)
    points = sweep_points(body.frequencies, rec["sample_rate_hz"], rec["samples"])
    groups = [("amplitudes_deg", i, {"amplitude_deg": a})
              for i, a in enumerate(body.amplitudes_deg)]
    groups += [("accelerations_dps2", i, {"accel_dps2": a})
               for i, a in enumerate(body.accelerations_dps2)]
    for key, index, size in groups:
        source = (*path, key, index)  # each step traces back to its own group element
        kept = [w.emit_or_skip(_sine_label(body.axis, motion, key == "amplitudes_deg"), source,
                               body.skip_outside_envelope, axis=body.axis,
                               inner_deg=body.inner_deg, outer_deg=body.outer_deg, **motion, **rec)
                for motion in (sine_motion(f, c, **size) for f, c in points)]
        if kept and not any(kept):
            raise w.fail(source, f"every one of the {len(kept)} points of this group lies "
                         f"outside the envelope ({w.skipped[-1].describe()}); remove or "
                         "reduce it")


def constant_rate(w: Walker, body: ConstantRate, path: YamlPath) -> None:
    """Emit one constant-rate step per listed rate."""
    for rate_dps in body.rates_dps:
        w.emit(f"rate-{body.axis}-{num(rate_dps)}dps", path, kind="constant_rate", axis=body.axis,
               rate_dps=rate_dps, inner_deg=body.inner_deg, outer_deg=body.outer_deg,
               group="constant-rate", **w.record(body))


def coordinated_rates(w: Walker, body: CoordinatedRates, path: YamlPath) -> None:
    """Inner at 360·f °/s, outer at α/ω_i (ω_i in rad/s): the sensor sees α·sin(ω_i t)."""
    rec = w.record(body)
    for nominal_hz in body.frequencies_hz:
        freq_hz, cycles = w.snap(nominal_hz, body.snap, rec)
        for accel_dps2 in body.accelerations_dps2:
            w.emit(f"coord-{freq_hz:.4f}Hz-{num(accel_dps2)}dps2", path, kind="constant_rate",
                   axis="both", rate_dps=360.0 * freq_hz,
                   outer_rate_dps=accel_dps2 / (2.0 * math.pi * freq_hz),
                   accel_dps2=accel_dps2, frequency_hz=freq_hz, cycles=cycles,
                   inner_deg=body.inner_deg, outer_deg=body.outer_deg,
                   group=f"coordinated-{num(accel_dps2)}", **rec)


def multi_position(w: Walker, body: MultiPosition, path: YamlPath) -> None:
    """Emit a static step per position, mounting and repetition, with the mounting prompts."""
    rec = w.record(body)
    for mount in body.mountings:
        mounting = Mounting(pivoted=mount == "pivoted")
        prompt: str | None = body.pivoted_prompt if mount == "pivoted" else body.original_prompt
        for rep in range(1, body.repetitions + 1):
            for inner_deg, outer_deg in body.positions:
                w.emit(f"static-i{num(inner_deg)}-o{num(outer_deg)}-{mount}-r{rep}", path, prompt,
                       kind="static", inner_deg=inner_deg, outer_deg=outer_deg,
                       motor_on=body.motor_on, repetition=rep, mounting=mounting,
                       group="multi-position", **rec)
                prompt = None


def temperature_steps(w: Walker, body: TemperatureSteps, path: YamlPath) -> None:
    """Per set-point: chamber soak, then (chamber off, wait) static and/or sine records."""
    for setpoint_c in body.setpoints_c:
        w.temperature_c = setpoint_c
        w.emit(f"chamber-{num(setpoint_c)}C", path, kind="chamber",
               sample_rate_hz=w.proc.sampling.rate_hz, group="temperature", **_soak(body))
        if body.static:
            w.emit(f"static-{num(setpoint_c)}C", path, kind="static", inner_deg=body.inner_deg,
                   outer_deg=body.outer_deg, group="temperature",
                   **w.record(body, settle_s=body.off_wait_s))
        if body.static and body.bias_pair:  # the same position with the sensitive axis down
            w.emit(f"static-o{num((body.outer_deg + 180.0) % 360.0)}-{num(setpoint_c)}C", path,
                   kind="static", inner_deg=body.inner_deg,
                   outer_deg=(body.outer_deg + 180.0) % 360.0, group="temperature",
                   **w.record(body, settle_s=body.off_wait_s))
        if body.dynamic is not None:
            _temperature_sine(w, body, path, setpoint_c)


def _soak(body: TemperatureSteps) -> dict[str, Any]:
    """The chamber step's soak: a fixed ``soak_s``, or until stable (the window is then the
    least soak, ``soak_max_s`` the most)."""
    if body.soak is None:
        return {"soak_s": body.soak_s}
    stable = body.soak.until_stable
    return {"soak_s": stable.window_s, "stable_tolerance_c": stable.tolerance_c,
            "stable_window_s": stable.window_s, "soak_max_s": body.soak.max_s}


def _temperature_sine(w: Walker, body: TemperatureSteps, path: YamlPath, setpoint_c: float) -> None:
    dyn = body.dynamic
    assert dyn is not None
    motion_settle = dyn.settle_s if dyn.settle_s is not None else w.record(body)["settle_s"]
    rec = w.record(body, settle_s=motion_settle + (0.0 if body.static else body.off_wait_s))
    freq_hz, cycles = w.snap(dyn.frequency_hz, dyn.snap, rec)
    motion = sine_motion(freq_hz, cycles, accel_dps2=dyn.accel_dps2)
    w.emit(f"{_sine_label(dyn.axis, motion, False)}-{num(setpoint_c)}C", path, axis=dyn.axis,
           inner_deg=body.inner_deg, outer_deg=body.outer_deg, **motion, **rec)


def misalignment(w: Walker, body: Misalignment, path: YamlPath) -> None:
    """Sets A..H × repetitions × experiments, with the operator's pivot/re-mount prompts."""
    rec = w.record(body)
    freq_hz, cycles = w.snap(body.frequency_hz, body.snap, rec)
    motion = sine_motion(freq_hz, cycles, accel_dps2=body.accel_dps2)
    for scenario in body.scenarios:
        pivoted, remount = scenario in "BDFH", REMOUNT[scenario]
        experiments = [e for e in body.experiments if (e >= FIRST_PIVOTED_EXPERIMENT) == pivoted]
        mounting_text = ("every sensor pivoted 180° about its sensitive axis" if pivoted
                         else "every sensor in its original orientation")
        for rep in range(1, body.repetitions + 1):
            prompt = f"Set {scenario}: {mounting_text}." if rep == 1 else None
            if remount != "none":
                prompt = " ".join(p for p in (prompt, f"Repetition {rep}/{body.repetitions}: "
                                  f"remove and re-mount {_REMOUNT_TEXT[remount]}.") if p)
            for experiment in experiments:
                axis = "inner" if experiment in (1, 4) else "outer"
                mounting = Mounting(pivoted=pivoted, remount=remount, scenario=scenario,
                                    experiment=experiment)
                w.emit(f"mis-{scenario}-e{experiment}-{axis}-r{rep}", path, prompt, axis=axis,
                       inner_deg=90.0 if experiment in (3, 6) else 0.0, outer_deg=0.0,
                       repetition=rep, mounting=mounting, **{**motion, "group": "misalignment"},
                       **rec)
                prompt = None


def repeat(w: Walker, body: Repeat, path: YamlPath) -> None:
    """Expand the nested steps ``count`` times, each repetition numbered in the step ids."""
    outer_rep, outer_suffix = w.repetition, w.rep_suffix
    for rep in range(1, body.count + 1):
        w.repetition, w.rep_suffix = rep, f"{outer_suffix}-r{rep}"
        w.walk(body.steps, (*path, "steps"))
    w.repetition, w.rep_suffix = outer_rep, outer_suffix


def operator(w: Walker, body: Operator, path: YamlPath) -> None:
    """Attach the prompt to the next step emitted (prompts in a row are joined)."""
    w.prompt = "\n".join(p for p in (w.prompt, body.prompt) if p)
