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

from aatest.twin.model import DaqModel
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
    # clip(round((v − lo)/lsb)·lsb + lo, lo, hi − lsb): the same operations in one buffer
    codes = np.subtract(volts, lo)
    codes /= lsb
    np.round(codes, out=codes)
    codes *= lsb
    codes += lo
    return np.clip(codes, lo, hi - lsb, out=codes)


def noiseless(clean_v: np.ndarray, daq: DaqModel, dt_s: float) -> np.ndarray:
    """The clean sensor output after the pre-sample filter (no noise, no ADC)."""
    if daq.antialias_hz is None:
        return clean_v
    b, a, _ = antialias_filter(float(daq.antialias_hz), round(dt_s, 15))
    return lowpass(clean_v, b, a)
