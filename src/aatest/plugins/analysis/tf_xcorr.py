"""The input–output delay of a transfer-function group, by cross-correlation (docs/method.md §4.4).

Per step, the normalised correlation of the table's acceleration (input) and the sensor's
channel (output) at lags 0..50 ms; summed over a group's steps, its peak gives the delay a
discrete model may carry, accepted only when the peak is strong. The sync pass computes each
step's term as it decodes the step (:func:`watch_xcorr`), so no step is decoded again here.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.fft import next_fast_len

from aatest.clocksync.freeze_pulse import SyncedStep
from aatest.engine.steps import PlannedStep
from aatest.plugins.analysis._common import (
    INPUT_ACCEL_CHANNELS,
    group_of,
    input_accel_channels,
    input_accel_dps2,
    is_excited,
)
from aatest.plugins.analysis.step_spectra import centred_rfft, input_key, output_key
from aatest.plugins.analysis.sync import SyncedSteps, SyncedWatch, watch_synced
from aatest.recording.dataset import Dataset, SensorInfo

#: normalised correlation peak at or above which the delay is accepted for the models
XCORR_MIN_STRENGTH = 0.9
#: the longest delay looked for (s)
_MAX_LAG_S = 0.05


def xcorr_delay(steps: Sequence[SyncedStep], sensor: SensorInfo) -> dict[str, float]:
    """Delay (s, whole samples) maximising the summed normalised input–output correlation.

    Reads only the table's acceleration and the sensor's channel of each step (a lazy view
    decodes nothing else).
    """
    return rated_xcorr(steps, sensor)[0]


def rated_xcorr(steps: Sequence[SyncedStep], sensor: SensorInfo) -> tuple[dict[str, float], float]:
    """:func:`xcorr_delay` and the steps' sample rate (Hz), each step synchronised once (or
    its correlation made by the sync pass, :func:`watch_xcorr`)."""
    if isinstance(steps, SyncedSteps):
        steps = steps.only(table=INPUT_ACCEL_CHANNELS, daq=(sensor.channel,))
        terms = steps.reduced(xcorr_watch_name(sensor), lambda s: _rated_term(s, sensor))
    else:
        terms = [_rated_term(s, sensor) for s in steps]
    if not terms:
        raise IndexError("no steps to correlate")
    fs = terms[0][0]
    max_lag = int(_MAX_LAG_S * fs)
    if any(rate != fs for rate, _ in terms):  # every step's lags are those of the first
        terms = [(fs, _xcorr_term(s, sensor, max_lag)) for s in steps]
    return summed_xcorr(terms)


def summed_xcorr(terms: Sequence[tuple[float, np.ndarray]]) -> tuple[dict[str, float], float]:
    """:func:`rated_xcorr` of a group's per-step terms ``(sample rate, correlation)``, every
    step at the first one's rate (the caller checks): their mean, its peak and the rate.
    One function for the pass and for the fits made while the run records
    (:mod:`aatest.plugins.analysis.tf_early`), so both sum in the same order."""
    fs = terms[0][0]
    max_lag = int(_MAX_LAG_S * fs)
    total = np.zeros(max_lag + 1)
    for _, term in terms:
        total += term
    total /= len(terms)
    lag = int(np.argmax(np.abs(total)))
    strength = float(abs(total[lag]))
    return {"delay_samples": lag, "delay_s": lag / fs, "strength": strength,
            "accepted": bool(strength >= XCORR_MIN_STRENGTH)}, fs


def _xcorr_term(s: SyncedStep, sensor: SensorInfo, max_lag: int) -> np.ndarray:
    """One step's normalised input–output correlation at lags 0..``max_lag`` (samples).

    From the records' own DFTs (the FRF point's, :mod:`~aatest.plugins.analysis.step_spectra`:
    inside the sync pass each is made once a step): their product is the circular correlation,
    and lag l of the linear one is that less the l products wrapped around the end (Σ over
    j < l of x[n−l+j]·y[j]), a few thousand products instead of three FFTs of n + max_lag;
    each record's deviation is its spectrum's power (Parseval), not another pass over it.
    """
    x = input_accel_dps2(s, sensor.axis)
    y = np.asarray(s.daq[sensor.channel], dtype=np.float64)
    if x.size != y.size or not 0 <= max_lag < x.size:
        return _padded_term(x, y, max_lag)
    n = x.size
    fx, fy = centred_rfft(x, input_key(s, sensor)), centred_rfft(y, output_key(s, sensor))
    spectra = np.conj(fx)
    spectra *= fy
    cc = np.fft.irfft(spectra, n)[:max_lag + 1]
    if max_lag:  # wrapped[l] = Σ_j tail[max_lag − l + j]·head[j]: a full convolution's end
        tail, head = x[n - max_lag:] - x.mean(), y[max_lag - 1::-1] - y.mean()
        cc[1:] -= np.convolve(tail, head)[max_lag - 1:][::-1]
    overlap = n - np.arange(cc.size)
    term: np.ndarray = cc / overlap / (_rms(fx, n) * _rms(fy, n))
    return term


def _rms(spectrum: np.ndarray, n: int) -> float:
    """√(mean x²) of the ``n`` samples x whose rfft is ``spectrum`` (Parseval: the bins
    between 0 and Nyquist stand for two each): the deviation of a centred record."""
    power = float(np.sum(spectrum.real**2)) + float(np.sum(spectrum.imag**2))
    ends = abs(spectrum[0]) ** 2 + (abs(spectrum[-1]) ** 2 if n % 2 == 0 else 0.0)
    return math.sqrt(max(2.0 * power - ends, 0.0)) / n


def _padded_term(x: np.ndarray, y: np.ndarray, max_lag: int) -> np.ndarray:
    """:func:`_xcorr_term` of records of different lengths: the linear correlation by FFTs
    padded past ``max_lag`` (no wrap-around)."""
    x, y = x - x.mean(), y - y.mean()
    # a 5-smooth length is ~10x faster than the next power of two above 2n
    nfft = next_fast_len(max(x.size, y.size) + max_lag, real=True)
    cc = np.fft.irfft(np.conj(np.fft.rfft(x, nfft)) * np.fft.rfft(y, nfft), nfft)
    return _normalised(cc[:max_lag + 1], x, y)


def _normalised(cc: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Correlation sums at lags 0.. over the overlap and the centred records' deviations."""
    overlap = x.size - np.arange(cc.size)
    term: np.ndarray = cc / overlap / (np.std(x) * np.std(y))
    return term


def _rated_term(s: SyncedStep, sensor: SensorInfo) -> tuple[float, np.ndarray]:
    """The step's sample rate (Hz) and its correlation over the lags that rate gives."""
    return s.sample_rate_hz, _xcorr_term(s, sensor, int(_MAX_LAG_S * s.sample_rate_hz))


def xcorr_watch_name(sensor: SensorInfo) -> str:
    """The name of the synced watch making ``sensor``'s per-step correlation terms."""
    return f"transfer_function.xcorr:{sensor.channel}"


def watch_xcorr(data: Dataset, min_points: int) -> None:
    """Have the sync pass correlate input and output of every sine step a model will read
    (groups with ``min_points`` steps along a sensor), as it decodes the step: each
    recorded step is then decoded once, not once more here (values identical)."""
    sine = [p for p in data.planned if p.kind == "sine"]
    for sensor in data.sensors:
        counts: dict[str, int] = {}
        for p in sine:
            if is_excited(p, sensor):
                counts[group_of(p)] = counts.get(group_of(p), 0) + 1
        modelled = {g for g, n in counts.items() if n >= min_points}

        def wanted(p: PlannedStep, sensor: SensorInfo = sensor,
                   modelled: set[str] = modelled) -> bool:
            return p.kind == "sine" and group_of(p) in modelled and is_excited(p, sensor)

        def term(s: SyncedStep, sensor: SensorInfo = sensor) -> tuple[float, np.ndarray]:
            return _rated_term(s, sensor)

        def channels(p: PlannedStep, sensor: SensorInfo = sensor) -> dict[str, tuple[str, ...]]:
            return {"table": input_accel_channels(p), "daq": (sensor.channel,)}

        watch_synced(data, xcorr_watch_name(sensor), SyncedWatch(channels, wanted, term))
