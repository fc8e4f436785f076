"""True values of the certified measurands, computed from the twin's own model.

The certificate states each quantity as a precise measurand (the ``measurand`` text the
uncertainty stage writes); this module evaluates the *same* measurand from the rig model, so
a calibration's result can be compared with the truth it should have found:

- scale factor: fundamental-bin ratio |V/α| of the sensor output (through the logger's
  pre-sample filter) to the angular acceleration about the sensor's mounting axis, at f and
  peak α, at the given temperature — sensor dynamics, transport delay, hysteresis,
  non-linearity at α, saturation, resolution, cross-axis and the sensor's *internal*
  misalignment included; the mounting (block and seat) errors, the table's errors and the
  logger's gain/offset error are not: those are errors of the measurement;
- FRF gain (dB) and phase (°): the same complex ratio of the fundamentals, in the steady
  state and in expectation over the motor band (the FRF analysis estimates it by the mean of
  Hann-weighted segment ratios: window-independent for periodic content, so the fit below
  over a few cycles states the same quantity);
- bias: the output at zero rate and acceleration at the temperature (g-sensitivity cancels in
  the ±1 g mean);
- g-sensitivity: the sensed acceleration per g along the sensor's axis, (°/s²)/g.

The ratio is evaluated by running the sensor model (:func:`aatest.twin.sensor.output_volts`)
on a noise-free, settled sine — exact for every effect of the model, however non-linear —
and fitting its fundamental (with the harmonics, so the window need not hold whole periods);
no noise, no ADC, no logger error.
"""

from __future__ import annotations

import math

import numpy as np

from aatest.twin import kinematics as kin
from aatest.twin.daq import noiseless
from aatest.twin.model import RigModel, SensorModel
from aatest.twin.sensor import SensorInputs, output_volts
from aatest.twin.table import Tones, make_vibration

__all__ = ["bias_truth_v", "frf_truth", "g_sensitivity_truth_dps2_per_g",
           "scale_factor_truth_v_per_dps2"]

#: settling cycles discarded before the analysed ones
_SETTLE_CYCLES = 3
#: analysed cycles
_CYCLES = 8
#: realisations of the motor band averaged: the band dithers the sensor's hysteresis, and one
#: draw's ratio differs from the mean by ≈0.002–0.006° in phase; 16 keep the mean's own error
#: ≲ 0.0015° (4 left ≈0.003° at 1 Hz, a tenth of the phase U the coverage bench checks)
_REALISATIONS = 16
#: harmonics fitted beside the fundamental (the sensor's non-linearity and hysteresis make them)
_HARMONICS = 5


def _mounted_axes(sensor: SensorModel) -> np.ndarray:
    """Sensor axes on a perfectly mounted seat: only the sensor's internal misalignment."""
    internal = (kin.tilt(sensor.misalignment.angle_deg, sensor.misalignment.azimuth_deg)
                if sensor.misalignment is not None else np.eye(3))
    return kin.SEAT_FRAMES[sensor.axis] @ internal


def _rotation_axis(sensor: SensorModel) -> np.ndarray:
    """The table-top direction of the sensor's nominal sensitive axis (the excited axis)."""
    return kin.SEAT_FRAMES[sensor.axis][:, 2]


def _ratio(model: RigModel, channel: str, frequency_hz: float, accel_dps2: float,
           temperature_c: float, seed: int | None = None) -> complex:
    """Complex ratio V/α (V per °/s²) of the fundamentals of one channel, from the model.

    The motor band of the inner axis (a random set of tones, :func:`make_vibration`) is part
    of the motion: it dithers the sensor's hysteresis. By default the ratio is the mean over
    ``_REALISATIONS`` seeded draws of the band; with a World ``seed`` that World's band is used
    (its tones, not its timing: the run's own phase relation to the record is not reproduced,
    so the mean is the better truth — a single draw differs by ≈0.01° in phase).
    """
    if seed is not None:
        from aatest.twin.world import World

        draws = [World(model, seed).vibration["inner"]]
    else:
        draws = [make_vibration(model.table.inner.motor_vibration, np.random.default_rng(k))
                 for k in range(_REALISATIONS)]
    ratios = [_ratio_once(model, channel, frequency_hz, accel_dps2, temperature_c, tones)
              for tones in draws]
    return complex(np.mean(ratios))


def _ratio_once(model: RigModel, channel: str, frequency_hz: float, accel_dps2: float,
                temperature_c: float, vibration: Tones | None) -> complex:
    """The ratio for one realisation of the motor band."""
    sensor = model.sensor(channel)
    # the logger's own sample spacing: its filters are discretised at it
    dt_s = 1.0 / model.daq.sample_rate_hz
    settle = math.ceil(_SETTLE_CYCLES / frequency_hz / dt_s)
    if sensor.amplitude_damping is not None:  # the amplitude's trailing window fills first
        settle += math.ceil(sensor.amplitude_damping.window_s / dt_s)
    n = settle + math.ceil(_CYCLES / frequency_hz / dt_s)
    t = np.arange(n) * dt_s
    delay = sensor.time_delay.delay_s if sensor.time_delay is not None else 0.0
    omega = 2.0 * math.pi * frequency_hz
    # start at rest in acceleration (sin), as a commanded sine does; the sensor sees it delayed
    alpha = accel_dps2 * np.sin(omega * (t - delay))
    rate = -accel_dps2 / omega * np.cos(omega * (t - delay))
    if vibration is not None:
        # the motor band is part of the motion the sensor sees: it dithers the hysteresis
        # (the play operator) and the rotor's stiction gap, which changes the fundamental
        phases = 2 * math.pi * np.outer(t - delay, vibration.frequency_hz) + vibration.phase_rad
        alpha = alpha + np.sin(phases) @ vibration.amplitude_dps2
        w_v = 2 * math.pi * vibration.frequency_hz
        rate = rate - np.cos(phases) @ (vibration.amplitude_dps2 / w_v)
    axis = _rotation_axis(sensor)
    inputs = SensorInputs(np.outer(axis, alpha), np.zeros((3, n)), np.full(n, temperature_c),
                          _mounted_axes(sensor), dt_s, rate_top_dps=np.outer(axis, rate))
    volts = noiseless(output_volts(sensor, inputs, model.t_ref_c), model.daq, dt_s)
    window = slice(settle, n)
    out = _fundamental(volts[window], omega * t[window])
    ref = _fundamental(accel_dps2 * np.sin(omega * t[window]), omega * t[window])
    return out / ref


def _fundamental(x: np.ndarray, phase_rad: np.ndarray) -> complex:
    """Complex amplitude c of the fundamental, x ≈ Re(c·e^{jωt}) + harmonics + mean.

    A Hann-weighted least-squares fit of the mean, the fundamental and harmonics 2..``_HARMONICS``.
    The window rarely holds a whole number of periods (the period is seldom a whole number of
    samples: 496.5 at 4.03 Hz and 2 kHz), and a plain windowed DFT bin then keeps a little of
    the negative-frequency image and of the harmonics, which differs between a delayed output
    and the reference (≈0.002° at 4 Hz over 8 cycles); the fit removes both exactly for any
    periodic content. The Hann weights keep the leakage of non-harmonic content (the motor
    band) falling off as 1/Δ³.
    """
    k = np.arange(1, _HARMONICS + 1)
    angles = np.outer(phase_rad, k)
    design = np.column_stack([np.ones_like(phase_rad), np.cos(angles), np.sin(angles)])
    weights = np.sqrt(np.hanning(x.size + 2)[1:-1])  # strictly positive Hann weights
    coef, *_ = np.linalg.lstsq(design * weights[:, None], x * weights, rcond=None)
    return complex(coef[1], -coef[1 + _HARMONICS])


def scale_factor_truth_v_per_dps2(model: RigModel, channel: str, frequency_hz: float,
                                  accel_dps2: float, temperature_c: float,
                                  seed: int | None = None) -> float:
    """True scale factor |V/α| at ``frequency_hz`` and peak ``accel_dps2`` (V/(°/s²)).

    Parameters
    ----------
    model
        The rig model the run was simulated with (incl. any drawn imperfections).
    channel
        Sensor channel, e.g. ``v_sz``.
    frequency_hz, accel_dps2
        The sine's frequency (Hz) and peak angular acceleration (°/s²).
    temperature_c
        Sensor temperature during the record (°C).
    seed
        The run's World seed: its motor-band realisation dithers the sensor's hysteresis
        (None: the mean over a few realisations).
    """
    return abs(_ratio(model, channel, frequency_hz, accel_dps2, temperature_c, seed))


def frf_truth(model: RigModel, channel: str, frequency_hz: float, accel_dps2: float,
              temperature_c: float, seed: int | None = None) -> tuple[float, float]:
    """True FRF point: (gain in dB re 1 V/(°/s²), phase in degrees) at f (Hz) and peak α
    (°/s²), temperature in °C; ``seed`` as for :func:`scale_factor_truth_v_per_dps2`."""
    ratio = _ratio(model, channel, frequency_hz, accel_dps2, temperature_c, seed)
    return 20.0 * math.log10(abs(ratio)), math.degrees(math.atan2(ratio.imag, ratio.real))


def bias_truth_v(model: RigModel, channel: str, temperature_c: float) -> float:
    """True bias K0: output at zero rate and acceleration at ``temperature_c`` (V)."""
    sensor = model.sensor(channel)
    n = 4  # a few samples: the jerk term needs a gradient
    inputs = SensorInputs(np.zeros((3, n)), np.zeros((3, n)), np.full(n, temperature_c),
                          _mounted_axes(sensor), 1.0 / model.daq.sample_rate_hz,
                          rate_top_dps=np.zeros((3, n)))
    return float(output_volts(sensor, inputs, model.t_ref_c)[0])


def g_sensitivity_truth_dps2_per_g(model: RigModel, channel: str) -> float:
    """True g-sensitivity: sensed acceleration per g along the sensor's mounting axis
    ((°/s²)/g); the internal misalignment's cosine is part of it."""
    sensor = model.sensor(channel)
    if sensor.g_sensitivity is None:
        return 0.0
    axes = _mounted_axes(sensor)
    projection = float(axes[:, 2] @ _rotation_axis(sensor))
    return sensor.g_sensitivity.coefficient_dps2_per_g * projection
