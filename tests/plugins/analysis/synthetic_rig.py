"""Synthetic two-logger recordings with known truth, for analysis tests (numpy only).

The motion is analytic (steady-state sines, or rest), the table log is the controller's
central-difference estimate of a noisy position estimate, and the DAQ runs on its own clock
(``t_table = t0 + t_daq·(1 + drift)``), emits the 100 Hz sync pulse and the trigger, and
records each sensor as ``bias + K·|H|·α(t − delay − phase)`` with a second-order H, an optional
cubic non-linearity, g-sensitivity and temperature terms, and white noise.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from aatest.engine.logs import SampledLog
from aatest.engine.steps import PlannedStep
from aatest.recording.dataset import Dataset, SensorInfo, StepData

FS_HZ = 2000.0


@dataclass(frozen=True)
class SynthSensor:
    channel: str = "v_sz"
    axis: str = "I"
    bias_v: float = 2.5
    scale_v_per_dps2: float = 0.004014
    natural_frequency_hz: float = 60.0
    damping: float = 0.7
    delay_s: float = 0.004
    noise_v: float = 0.001
    c3: float = 0.0
    range_dps2: float = 572.958
    g_dps2_per_g: float = 0.0
    bias_tc_v_per_c: float = 0.0
    scale_tc_per_c: float = 0.0
    cross_x: float = 0.0  # response to table-frame x-axis acceleration, relative
    cross_y: float = 0.0


@dataclass(frozen=True)
class SynthRig:
    sensors: tuple[SynthSensor, ...] = (SynthSensor(),)
    drift_ppm: float = 12.0
    lead_s: float = 0.3512
    lag_s: float = 0.4
    position_noise_deg: float = 0.2 / 3600
    latch: bool = True
    jitter_s: float = 0.0
    t_ref_c: float = 25.0
    extra: dict = field(default_factory=dict)


def sine_step(step_id: str, cycles: int, accel_dps2: float, samples: int = 16384,
              axis: str = "inner", **kw: object) -> PlannedStep:
    f = cycles * FS_HZ / samples
    amp = accel_dps2 / (2 * np.pi * f) ** 2
    return PlannedStep(id=step_id, kind="sine", axis=axis, samples=samples,
                       duration_s=samples / FS_HZ, frequency_hz=f, cycles=cycles,
                       amplitude_deg=amp, accel_dps2=accel_dps2, **kw)


def static_step(step_id: str, inner_deg: float, outer_deg: float, samples: int = 8192,
                **kw: object) -> PlannedStep:
    return PlannedStep(id=step_id, kind="static", axis="none", samples=samples,
                       duration_s=samples / FS_HZ, inner_deg=inner_deg, outer_deg=outer_deg, **kw)


def _motion(step: PlannedStep, t_s: np.ndarray, phase_rad: float) -> tuple[np.ndarray, np.ndarray]:
    """(position_deg, accel_dps2) of the moving axis at table-clock times t_s."""
    if step.kind != "sine":
        zero = np.zeros_like(t_s)
        return zero, zero
    w = 2 * np.pi * float(step.frequency_hz)
    arg = w * t_s + phase_rad
    amp = float(step.amplitude_deg)
    return amp * np.sin(arg), -amp * w**2 * np.sin(arg)


def _sensor_gain(s: SynthSensor, f_hz: float) -> complex:
    wn = 2 * np.pi * s.natural_frequency_hz
    jw = 2j * np.pi * f_hz
    return complex(wn**2 / (jw**2 + 2 * s.damping * wn * jw + wn**2) * np.exp(-jw * s.delay_s))


def _input_weight(s: SynthSensor, step: PlannedStep) -> float:
    """Projection of the moving axis onto the sensor axis (+ cross-axis pick-up)."""
    psi = np.deg2rad(step.inner_deg)
    if step.axis == "inner":
        return {"I": 1.0, "O": s.cross_y, "P": s.cross_x}[s.axis]
    if step.axis == "outer":
        o_on, p_on = np.cos(psi), np.sin(psi)
        return {"I": s.cross_y * o_on + s.cross_x * p_on, "O": o_on, "P": p_on}[s.axis]
    return 0.0


def _gravity_g(s: SynthSensor, step: PlannedStep) -> float:
    """Specific force along the sensor axis in g for a static table orientation."""
    o, i = np.deg2rad(step.outer_deg), np.deg2rad(step.inner_deg)
    up = {"I": np.cos(o), "O": np.sin(o) * np.sin(i), "P": -np.sin(o) * np.cos(i)}
    return float(up[s.axis])


def _sensor_volts(s: SynthSensor, step: PlannedStep, t_s: np.ndarray, phase: float,
                  temp_c: float, rng: np.random.Generator) -> np.ndarray:
    weight = _input_weight(s, step)
    accel = np.zeros_like(t_s)
    if step.kind == "sine" and weight != 0.0:
        h = _sensor_gain(s, float(step.frequency_hz))
        amp = float(step.amplitude_deg) * (2 * np.pi * float(step.frequency_hz)) ** 2
        accel = -weight * amp * abs(h) * np.sin(2 * np.pi * step.frequency_hz * t_s + phase
                                                + np.angle(h))
    accel = accel * (1 + s.c3 * (accel / s.range_dps2) ** 2) + s.g_dps2_per_g * _gravity_g(s, step)
    dt_c = temp_c - 25.0
    scale = s.scale_v_per_dps2 * (1 + s.scale_tc_per_c * dt_c)
    bias = s.bias_v + s.bias_tc_v_per_c * dt_c
    return bias + scale * accel + rng.normal(0, s.noise_v, t_s.size)


def _table_log(step: PlannedStep, rig: SynthRig, phase: float, pulse_edges_table_s: np.ndarray,
               rng: np.random.Generator) -> SampledLog:
    n = step.samples
    t = np.arange(n) / FS_HZ
    pos, _ = _motion(step, t, phase)
    pos_est = pos + rng.normal(0, rig.position_noise_deg, n)
    ext = np.concatenate([[2 * pos_est[0] - pos_est[1]], pos_est, [2 * pos_est[-1] - pos_est[-2]]])
    rate = (ext[2:] - ext[:-2]) * FS_HZ / 2
    accel = (ext[2:] - 2 * ext[1:-1] + ext[:-2]) * FS_HZ**2
    # freeze pulse: every DAQ edge is registered one controller cycle late, latch time logged
    reg = np.floor(pulse_edges_table_s * FS_HZ).astype(int) + 1
    state = (np.arange(reg.size) % 2 == 0).astype(float)  # edges alternate rising/falling
    last = np.searchsorted(reg, np.arange(n), side="right") - 1
    pulse = np.where(last >= 0, state[np.clip(last, 0, None)], 0.0)
    rising_reg, rising_t = reg[0::2], pulse_edges_table_s[0::2]
    last_r = np.searchsorted(rising_reg, np.arange(n), side="right") - 1
    latch = np.where(last_r >= 0, (rising_reg / FS_HZ - rising_t)[np.clip(last_r, 0, None)], 0.0)
    channels = {f"{ax}_{q}": np.zeros(n) for ax in ("inner", "outer")
                for q in ("position_deg", "rate_dps", "accel_dps2", "feedback_deg")}
    moving = step.axis if step.axis in ("inner", "outer") else "inner"
    channels[f"{moving}_position_deg"] = pos_est + (step.inner_deg if moving == "inner" else
                                                    step.outer_deg)
    channels[f"{moving}_rate_dps"] = rate
    channels[f"{moving}_accel_dps2"] = accel
    channels[f"{moving}_feedback_deg"] = pos + rng.normal(0, rig.position_noise_deg, n)
    fixed = "outer" if moving == "inner" else "inner"
    channels[f"{fixed}_position_deg"] += step.outer_deg if fixed == "outer" else step.inner_deg
    channels["sync_pulse"] = pulse
    if rig.latch:
        channels["fp_latch_s"] = latch
    return SampledLog("table", FS_HZ, t, channels)


def make_step(step: PlannedStep, rig: SynthRig, seed: int, temperature_c: float = 25.0
              ) -> StepData:
    """One synthetic step; the truth is in ``rig`` (clock, sensors) and ``step`` (motion)."""
    rng = np.random.default_rng(seed)
    phase = float(rng.uniform(0, 2 * np.pi))
    k = 1 + rig.drift_ppm * 1e-6
    t0 = -rig.lead_s
    n_daq = int((step.samples / FS_HZ + rig.lead_s + rig.lag_s) * FS_HZ)
    j = np.arange(n_daq)
    t_daq = j / FS_HZ
    t_tab = t0 + t_daq * k  # table-clock instant of each DAQ sample
    pulse = ((j // 10) % 2 == 0).astype(float)
    edge_idx = np.flatnonzero(np.diff(pulse) != 0) + 1  # alternating rising/falling
    if pulse[edge_idx[0]] < 0.5:
        edge_idx = edge_idx[1:]
    table = _table_log(step, rig, phase, t_tab[edge_idx], rng)
    daq = {"sync_pulse": pulse, "trigger": (t_tab >= 0).astype(float),
           "temperature_c": np.full(n_daq, temperature_c)}
    for s in rig.sensors:
        daq[s.channel] = _sensor_volts(s, step, t_tab, phase, temperature_c, rng)
    stamps = t_daq + rng.normal(0, rig.jitter_s, n_daq) if rig.jitter_s else t_daq
    return StepData(step=step, table=table, daq=SampledLog("daq", FS_HZ, stamps, daq))


def make_dataset(steps: list[PlannedStep], rig: SynthRig, seed: int = 1,
                 temperatures_c: list[float] | None = None) -> Dataset:
    temps = temperatures_c or [25.0] * len(steps)
    pairs = enumerate(zip(steps, temps, strict=True))
    data = tuple(make_step(s, rig, seed + i, t) for i, (s, t) in pairs)
    infos = tuple(SensorInfo(channel=s.channel, axis=s.axis)  # type: ignore[arg-type]
                  for s in rig.sensors)
    return Dataset(procedure="synthetic", sample_rate_hz=FS_HZ, sensors=infos, steps=data,
                   source=Path("synthetic"))
