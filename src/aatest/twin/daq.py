"""The sensor logger's analogue chain: 100 Hz pre-sample filter, noise, slip ring, ADC.

The sensor's white noise is injected before the anti-alias filter and scaled by the filter's
noise gain, so ``SensorModel.noise_rms_v`` is the RMS the logger actually records (the measured
≈1 mV of docs/method.md §1.3). Slip-ring and ``excess_noise`` terms are added after the filter as
white noise (≈11 mV RMS measured for the ring).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy import signal

from aatest.twin.fastmath import standard_normal
from aatest.twin.model import DaqModel, SensorModel
from aatest.twin.sensor import lowpass

#: order of the Butterworth pre-sample filter
ANTIALIAS_ORDER = 2


@lru_cache(maxsize=16)
def antialias_filter(corner_hz: float, dt_s: float) -> tuple[np.ndarray, np.ndarray, float]:
    """(b, a, noise_gain) of the analogue Butterworth pre-sample filter, discretised bilinearly.

    ``noise_gain`` is the RMS gain for white noise, √Σh², from the impulse response.
    """
    b_s, a_s = signal.butter(ANTIALIAS_ORDER, 2 * np.pi * corner_hz, analog=True)
    b, a = signal.bilinear(b_s, a_s, fs=1.0 / dt_s)
    impulse = signal.lfilter(b, a, np.r_[1.0, np.zeros(4095)])
    return b, a, float(np.sqrt(np.sum(impulse**2)))


def quantise_adc(volts: np.ndarray, daq: DaqModel) -> np.ndarray:
    """ADC conversion: clip to the input range and round to one LSB."""
    lo, hi = daq.adc_range_v
    lsb = (hi - lo) / 2**daq.adc_bits
    return np.clip(np.round((volts - lo) / lsb) * lsb + lo, lo, hi - lsb)


def record_channel(clean_v: np.ndarray, sensor: SensorModel, daq: DaqModel, dt_s: float,
                   rng: np.random.Generator) -> np.ndarray:
    """Logged volts of one channel: (clean + noise) through the pre-sample filter, extra
    white noise (slip ring, ``excess_noise``), then the ADC."""
    signal_v = clean_v
    if sensor.noise_rms_v:
        gain = antialias_filter(float(daq.antialias_hz), round(dt_s, 15))[2] \
            if daq.antialias_hz is not None else 1.0
        signal_v = clean_v + (sensor.noise_rms_v / gain) * standard_normal(rng, clean_v.size)
    filtered = noiseless(signal_v, daq, dt_s)
    extra = [n.rms_v for n in (sensor.excess_noise, daq.slip_ring) if n is not None and n.rms_v]
    if extra:
        filtered = filtered + float(np.hypot.reduce(extra)) * standard_normal(rng, clean_v.size)
    if daq.logger_error is not None:  # the logger's own gain and offset error (drawn)
        filtered = (1.0 + daq.logger_error.gain_error) * filtered + daq.logger_error.offset_v
    return quantise_adc(filtered, daq)


def noiseless(clean_v: np.ndarray, daq: DaqModel, dt_s: float) -> np.ndarray:
    """The clean sensor output after the pre-sample filter (no noise, no ADC)."""
    if daq.antialias_hz is None:
        return clean_v
    b, a, _ = antialias_filter(float(daq.antialias_hz), round(dt_s, 15))
    return lowpass(clean_v, b, a)
