"""Import directories with two or three simultaneous effects, written from the sensor physics.

Like :mod:`foreign_dataset` this writes what another tool would record (contract §3 only, no
aatest simulation code): a position table on its own clock with a 100 Hz freeze pulse, a DAQ
on a crystal clock that starts 0.3 s earlier, and one servo accelerometer channel. The sensor
follows the error model of docs/method.md §1.3 in its physical order — the motion reaches the
sensing element late (transport delay), the fluid rotor's backlash (play operator), its
second-order dynamics, the servo's output limit, the static non-linearity, the scale factor
K(T) and its ageing, then the additive terms (bias b(T), jerk pickup, mains pickup, bias step),
the sensor noise and the excess noise of the cabling — so any subset of effects composes the
way a real unit would produce it, not the way the diagnosis models it.

Effects are contract vocabulary (docs/interfaces.md §4 names and units) or out of vocabulary
(the kinds of :mod:`foreign_dataset`). The plan has ten steps: sines from 0.5 to 8 Hz and
20 to 400 °/s² (every timing, shape and amplitude effect shows), two statics, and step
temperatures cycled so that temperature, time and amplitude are not confounded.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from foreign_dataset import (
    BIAS_V,
    DAQ_LEAD_S,
    FS_HZ,
    K_V_PER_DPS2,
    MAINS_HZ,
    RANGE_DPS2,
    _square_100hz,
    _table_log,
    write_step_csvs,
)
from scipy import signal

#: (kind, frequency Hz, peak acceleration °/s²) of each step
PLAN = (("sine", 1.0, 100.0), ("sine", 2.0, 200.0), ("sine", 4.0, 300.0), ("sine", 0.5, 50.0),
        ("static", 0.0, 0.0), ("static", 0.0, 0.0), ("sine", 3.0, 400.0), ("sine", 6.0, 100.0),
        ("sine", 8.0, 150.0), ("sine", 1.5, 20.0))
#: step temperatures (°C): cycled, so temperature is not a proxy for time or amplitude
TEMPS_C = (25.0, 40.0, 10.0, 35.0, 15.0, 45.0, 20.0, 5.0, 30.0, 25.0)
T_REF_C = 25.0
SENSOR_NOISE_V = 0.001
#: step (index) whose record holds the ``bias_step`` and where (share of the record)
BIAS_STEP_AT = (2, 0.6)
VOCABULARY = ("bias_temperature", "scale_temperature", "nonlinearity_cubic", "saturation",
              "hysteresis", "sensor_dynamics", "time_delay", "clock_drift", "jerk_sensitivity",
              "excess_noise")
OUT_OF_VOCABULARY = ("even_order", "asymmetric_scale", "mains_50hz", "bias_step", "scale_ageing")


@dataclass(frozen=True)
class Effect:
    """One effect in a dataset: contract name and parameters (contract units), or OOV kind."""

    effect: str
    parameters: tuple[tuple[str, float], ...]

    def __getitem__(self, key: str) -> float:
        return dict(self.parameters)[key]

    @property
    def in_vocabulary(self) -> bool:
        return self.effect in VOCABULARY


def effect(name: str, **parameters: float) -> Effect:
    """An :class:`Effect` from keyword parameters (contract names and units)."""
    return Effect(name, tuple(sorted(parameters.items())))


@dataclass(frozen=True)
class _Record:
    """What the sensor saw during one DAQ record."""

    t_tab_s: np.ndarray
    t_daq_s: np.ndarray
    elapsed_s: np.ndarray
    temp_c: float
    kind: str
    f_hz: float
    accel_dps2: float
    step: int


def _alpha(rec: _Record, delay_s: float, derivative: bool = False) -> np.ndarray:
    """α (°/s²) or dα/dt (°/s³) of the table motion felt ``delay_s`` late (table clock)."""
    if rec.kind != "sine":
        return np.zeros_like(rec.t_tab_s)
    w = 2 * np.pi * rec.f_hz
    phase = w * (rec.t_tab_s - delay_s)
    return -rec.accel_dps2 * (w * np.cos(phase) if derivative else np.sin(phase))


def play(x: np.ndarray, half_width: float) -> np.ndarray:
    """Play (backlash) operator of half width ``half_width``, starting centred.

    Vectorised over monotone runs: on a rising run the output is max(x − r, its value at the
    run start), on a falling run min(x + r, …); only the few run starts are sequential.
    """
    if half_width <= 0 or x.size < 2:
        return x.copy()
    rising = np.diff(x) >= 0
    starts = np.concatenate([[0], np.flatnonzero(rising[1:] != rising[:-1]) + 1, [x.size - 1]])
    y = np.empty_like(x)
    y0 = float(x[0])
    for a, b in itertools.pairwise(starts):
        seg = x[a:b + 1]
        y[a:b + 1] = (np.maximum(seg - half_width, y0) if rising[a]
                      else np.minimum(seg + half_width, y0))
        y0 = float(y[b])
    return y


def _second_order(alpha: np.ndarray, fn_hz: float, zeta: float) -> np.ndarray:
    """ωn²/(s² + 2ζωn·s + ωn²) on α (bilinear transform, started at rest)."""
    wn = 2 * np.pi * fn_hz
    b, a = signal.bilinear([wn * wn], [1.0, 2 * zeta * wn, wn * wn], fs=FS_HZ)
    return signal.lfilter(b, a, alpha)


def _sensed(rec: _Record, fx: dict[str, Effect]) -> np.ndarray:
    """The sensing element's output before K (°/s²): delay, backlash, dynamics, limit, shape."""
    delay = fx["time_delay"]["delay_s"] if "time_delay" in fx else 0.0
    a = _alpha(rec, delay)
    if "hysteresis" in fx:
        a = play(a, fx["hysteresis"]["half_width_dps2"])
    if "sensor_dynamics" in fx:
        e = fx["sensor_dynamics"]
        a = _second_order(a, e["natural_frequency_hz"], e["damping"])
    if "saturation" in fx:
        lim = fx["saturation"]["limit_dps2"]
        a = np.clip(a, -lim, lim)
    out = a.copy()
    if "nonlinearity_cubic" in fx:
        out += fx["nonlinearity_cubic"]["c3"] * a * (a / RANGE_DPS2) ** 2
    if "even_order" in fx:
        out += fx["even_order"]["c2"] * a**2 / RANGE_DPS2
    if "asymmetric_scale" in fx:
        out *= np.where(a > 0, 1 + fx["asymmetric_scale"]["a"] / 2,
                        1 - fx["asymmetric_scale"]["a"] / 2)
    return out


def _sensor_v(rec: _Record, fx: dict[str, Effect], rng: np.random.Generator) -> np.ndarray:
    """Sensor voltage (V): K(T)·sensed + b(T) + additive pickups + noise."""
    dt_c = rec.temp_c - T_REF_C
    k = K_V_PER_DPS2 * (1 + (fx["scale_temperature"]["coefficient_per_c"] * dt_c
                             if "scale_temperature" in fx else 0.0))
    if "scale_ageing" in fx:
        k = k * (1 + fx["scale_ageing"]["per_h"] * rec.elapsed_s / 3600.0)
    v = BIAS_V + k * _sensed(rec, fx)
    if "bias_temperature" in fx:
        v += fx["bias_temperature"]["coefficient_v_per_c"] * dt_c
    if "jerk_sensitivity" in fx:
        delay = fx["time_delay"]["delay_s"] if "time_delay" in fx else 0.0
        v += fx["jerk_sensitivity"]["coefficient_v_per_dps3"] * _alpha(rec, delay, True)
    if "mains_50hz" in fx:
        v += fx["mains_50hz"]["amplitude_v"] * np.sin(2 * np.pi * MAINS_HZ * rec.t_daq_s + 0.4)
    if "bias_step" in fx and rec.step == BIAS_STEP_AT[0]:
        t = rec.t_daq_s - DAQ_LEAD_S
        v += fx["bias_step"]["delta_v"] * (t >= BIAS_STEP_AT[1] * t[-1])
    noise = SENSOR_NOISE_V
    if "excess_noise" in fx:
        noise = float(np.hypot(noise, fx["excess_noise"]["rms_v"]))
    return v + rng.normal(0.0, noise, v.size)


def write_multi(out: Path, effects: tuple[Effect, ...] = (), samples: int = 8192,
                latch: bool = True, seed: int = 0) -> Path:
    """Write ``out/dataset.yaml`` and one table/DAQ CSV pair per step; return ``out``."""
    fx = {e.effect: e for e in effects}
    rng = np.random.default_rng(seed)
    out.mkdir(parents=True, exist_ok=True)
    drift = (fx["clock_drift"]["drift_ppm"] if "clock_drift" in fx else 5.0) * 1e-6
    entries, session_s = [], 0.0
    for k, ((kind, f_nominal, accel), temp_c) in enumerate(zip(PLAN, TEMPS_C, strict=True)):
        sid = f"s{k + 1:02d}"
        f_hz = round(f_nominal * samples / FS_HZ) * FS_HZ / samples  # coherent: whole cycles
        table, _, _ = _table_log(samples, kind, f_hz, accel, drift, rng)
        t_daq = np.arange(samples + int(0.5 * FS_HZ)) / FS_HZ
        t_tab = -DAQ_LEAD_S + t_daq * (1 + drift)
        rec = _Record(t_tab, t_daq, session_s + t_daq, temp_c, kind, f_hz, accel, k)
        session_s += float(t_daq[-1])
        daq = np.column_stack([t_daq + 1000.0, _square_100hz(t_daq), (t_tab >= 0).astype(int),
                               _sensor_v(rec, fx, rng), np.full(t_daq.size, temp_c)])
        write_step_csvs(out, sid, table, latch, daq, "time_s,sync_pulse,trigger,v_sz,temperature_c")
        sine = f"frequency_hz: {f_hz!r}, accel_dps2: {accel}, " if kind == "sine" else ""
        entries.append(f"  - {{id: {sid}, kind: {kind}, axis: inner, {sine}inner_deg: 0, "
                       f"outer_deg: 0, temperature_c: {temp_c}, table: {sid}_table.csv, "
                       f"daq: {sid}_daq.csv}}")
    (out / "dataset.yaml").write_text(
        "sensors:\n  - {channel: v_sz, axis: I, nominal_bias_v: 2.5, "
        f"nominal_scale_v_per_dps2: {K_V_PER_DPS2}, range_dps2: {RANGE_DPS2}, "
        f"noise_rms_v: {SENSOR_NOISE_V}}}\n"
        f"sample_rate_hz: {FS_HZ:g}\nt_ref_c: {T_REF_C}\nsteps:\n" + "\n".join(entries) + "\n")
    return out
