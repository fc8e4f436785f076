"""What the recorded data show about the budget's Type B components: motion and temperature.

The uncertainty stage reads the results; a few components are measured from the logs
themselves: the distortion of the table's motion (THD of the position log, harmonics 2–5 in
acceleration) and the servo's non-commanded content at the fundamental, and the temperature
logged beside the sensor during each record. One pass over the recording, vectorised (an FFT
of each record read: the position, the table's acceleration, whose spectrum the FRF point
reuses (:mod:`aatest.record_spectra`), and each sensor's volts); without a recording (a
results.json re-read alone) the components are reported as not evaluated.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from aatest.record_spectra import BY_MEMORY, centred_rfft

#: harmonics of the fundamental summed into the motion THD
HARMONICS = 5


@dataclass(frozen=True)
class MotionEvidence:
    """Distortion of one sine record's table motion, from the position log."""

    thd_accel: float
    """THD of the acceleration (harmonics 2..5 over the fundamental, k² weighted), ratio"""
    tracking_rel: float
    """|measured fundamental amplitude / commanded − 1| of the position, ratio"""


@dataclass(frozen=True)
class BinNoise:
    """Noise next to the fundamental bin of one sine record, relative to the fundamental.

    ``table_rel`` is for the table's acceleration estimate, ``channels_rel`` per sensor channel;
    each is the standard uncertainty of the fundamental's amplitude (and phase, rad), from the
    mean power of the bins 3–40 away from it (harmonic bins excluded) — the noise where the
    bin is, not the record's average (differentiated encoder noise rises with f, the logger's
    pre-sample filter shapes the sensor noise).
    """

    table_rel: float
    channels_rel: dict[str, float]


@dataclass(frozen=True)
class StaticLine:
    """The strongest spectral line of a static record's output and what it leaves in its mean.

    A line of peak amplitude V at f (e.g. the motor band) does not average out of a mean over
    T seconds: at most V/(π·f·T) of it stays, whatever its phase.
    """

    amplitude_v: float
    frequency_hz: float
    residual_bound_v: float


@dataclass(frozen=True)
class TemperatureEvidence:
    """Temperature logged beside the sensor during one record."""

    mean_c: float
    std_c: float


@dataclass(frozen=True)
class Evidence:
    """Per step id: the motion and temperature measured from the recording."""

    motion: dict[str, MotionEvidence] = field(default_factory=dict)
    temperature: dict[str, TemperatureEvidence] = field(default_factory=dict)
    recording: bool = False
    bin_noise: dict[str, BinNoise] = field(default_factory=dict)
    static_lines: dict[str, dict[str, StaticLine]] = field(default_factory=dict)

    def static_line_bound_v(self, channel: str, step_ids: list[str]) -> StaticLine | None:
        """The line with the largest residual bound (V) over the given static records."""
        lines = [self.static_lines[s][channel] for s in step_ids
                 if channel in self.static_lines.get(s, {})]
        return max(lines, key=lambda line: line.residual_bound_v) if lines else None

    def temperature_over(self, step_ids: list[str] | None = None) -> TemperatureEvidence | None:
        """Mean and spread of the logged temperature over the given steps (all when None)."""
        ids = list(self.temperature) if step_ids is None else \
            [s for s in step_ids if s in self.temperature]
        if not ids:
            return None
        means = np.array([self.temperature[s].mean_c for s in ids])
        stds = np.array([self.temperature[s].std_c for s in ids])
        spread = float(np.sqrt(np.mean(stds**2) + np.var(means)))
        return TemperatureEvidence(float(np.mean(means)), spread)


def _motion(position_deg: np.ndarray, cycles: int, amplitude_deg: float) -> MotionEvidence | None:
    """THD and tracking of a coherent sine record (``cycles`` whole periods)."""
    n = position_deg.size
    if cycles < 1 or n < 4 * HARMONICS * cycles:
        return None
    spectrum = centred_rfft(position_deg)  # rfft(x − mean(x)), nothing kept
    fundamental = abs(spectrum[cycles]) * 2.0 / n
    if fundamental <= 0:
        return None
    k = np.arange(2, HARMONICS + 1)
    harmonics = np.abs(spectrum[k * cycles]) * 2.0 / n
    thd = float(np.sqrt(np.sum((k**2 * harmonics) ** 2)) / fundamental)
    tracking = abs(fundamental / amplitude_deg - 1.0) if amplitude_deg else math.nan
    return MotionEvidence(thd, float(tracking))


#: bins either side of the fundamental whose power estimates the noise at it
_NEAR_BINS = np.arange(3, 41)


def local_noise_rel(x: np.ndarray, cycles: int, shared: bool = False) -> float | None:
    """Relative (dimensionless) standard uncertainty of the fundamental of ``x`` (``cycles``
    periods in its ``n`` samples): √(mean |X_k|²/2)/|X_1| over the bins near the fundamental.

    ``shared``: ``x`` is a record the FRF point transforms too (the table's acceleration):
    its spectrum is made once (:func:`aatest.record_spectra.centred_rfft`).
    """
    n = x.size
    if cycles < 1 or n < 8 * cycles:
        return None
    raw = centred_rfft(x, BY_MEMORY if shared else None)
    near = np.concatenate([cycles - _NEAR_BINS, cycles + _NEAR_BINS])
    near = near[(near > 0) & (near < raw.size) & (near % cycles != 0)]
    # only the bins read are scaled to peak amplitudes (the same operations on each)
    fundamental = abs(raw[cycles] * 2.0 / n)
    if near.size == 0 or fundamental <= 0:
        return None
    return float(np.sqrt(np.mean(np.abs(raw[near] * 2.0 / n) ** 2) / 2.0) / fundamental)


#: a 0/1 logic channel (the DAQ's trigger) is high above half its swing
_LOGIC_HIGH = 0.5


def _table_start_on_daq(record: Any, spare: int) -> int:
    """DAQ sample of the table record's first sample, by the clock relation's anchor.

    The DAQ raises its trigger on one of its own samples and that starts the table log, so the
    table's first sample *is* the trigger's first high DAQ sample: the sync analysis pins the
    fitted relation's offset to it (``aatest.clocksync.freeze_pulse.refine_offset``). The clock
    drift stretches the rest by ≤ 1e-4 of the record (≤ 13 samples at 2^17 and 100 ppm), which
    leaves the bins near a coherent fundamental as they are. Without a trigger channel (data
    imported without one) the DAQ record is taken as bracketing the table one evenly.
    """
    trigger = record.daq.channels.get("trigger")
    if trigger is not None:
        high = np.asarray(trigger, dtype=float) > _LOGIC_HIGH
        first = int(np.argmax(high))  # the first high sample (0 when none is)
        if high.size and high[first] and first <= spare:
            return first
    return spare // 2


def _bin_noise(record: Any, cycles: int, channels: list[str]) -> BinNoise | None:
    """Local noise of the table estimate and of each sensor channel of one sine record."""
    step = record.step
    accel = record.table.channels.get(f"{step.axis}_accel_dps2")
    if accel is None:
        return None
    table = local_noise_rel(np.asarray(accel, dtype=float), cycles, shared=True)
    n = np.size(accel)
    per_channel = {}
    for channel in channels:
        volts = record.daq.channels.get(channel)
        if volts is None or np.size(volts) < n:
            continue
        start = _table_start_on_daq(record, np.size(volts) - n)
        rel = local_noise_rel(np.asarray(volts[start:start + n], dtype=float), cycles)
        if rel is not None:
            per_channel[channel] = rel
    return BinNoise(table, per_channel) if table is not None else None


#: a record shorter than this has no spectrum worth the name
_MIN_STATIC_SAMPLES = 64
#: lines below this frequency are drift, not a periodic disturbance
_LINE_MIN_HZ = 2.0
#: most samples of a static record whose spectrum is searched for its strongest line
LINE_SAMPLES = 2**20


def static_line(volts: np.ndarray, sample_rate_hz: float) -> StaticLine | None:
    """The strongest line above 2 Hz of a static record, as a peak amplitude, with the bound
    of its residual in the record mean (Hann-windowed spectrum, amplitude-corrected).

    The spectrum is taken over at most the first :data:`LINE_SAMPLES` samples (524 s at
    2 kHz); the bound is over the whole record's duration, because the mean it bounds is the
    whole record's. Why: a rig line is stationary, and 2**20 samples already resolve it to
    0.002 Hz at 2 kHz, while the FFT of an hours-long record (14 M samples for 2 h) costs
    about 1 GB in window, spectrum and frequency arrays for no better estimate of the line.
    Records up to that length are analysed whole, as before.
    """
    return line_of_head(volts[:LINE_SAMPLES], volts.size, sample_rate_hz)


def line_of_head(head: np.ndarray, samples: int, sample_rate_hz: float) -> StaticLine | None:
    """:func:`static_line` from the record's first ``LINE_SAMPLES`` (or fewer) samples
    ``head`` (V), its whole length ``samples`` and its ``sample_rate_hz`` (Hz): all a streamed
    record needs to keep."""
    if samples < _MIN_STATIC_SAMPLES:
        return None
    head = np.asarray(head[:LINE_SAMPLES], dtype=float)
    window = np.hanning(head.size)
    spec = np.abs(np.fft.rfft((head - np.mean(head)) * window)) * 2.0 / np.sum(window)
    freqs = np.fft.rfftfreq(head.size, 1.0 / sample_rate_hz)
    band = freqs >= _LINE_MIN_HZ
    if not np.any(band):
        return None
    k = int(np.argmax(np.where(band, spec, 0.0)))
    amplitude, f_hz = float(spec[k]), float(freqs[k])
    duration_s = samples / sample_rate_hz
    return StaticLine(amplitude, f_hz, amplitude / (math.pi * f_hz * duration_s))


#: the DAQ's temperature channel, read beside every record
_TEMPERATURE = "temperature_c"


@dataclass
class Moments:
    """Mean and (population) standard deviation of values fed in pieces, in their unit.

    Pieces are merged with the pairwise update of Chan, Golub and LeVeque: one piece gives
    exactly ``np.mean`` and ``np.std``; several agree with them to rounding (≈1e-16 relative),
    without keeping the values.
    """

    count: int = 0
    mean: float = 0.0
    m2: float = 0.0

    def add(self, values: np.ndarray) -> None:
        """Feed the next values."""
        n = int(np.size(values))
        if not n:
            return
        mean = float(np.mean(values))
        m2 = float(np.sum((np.asarray(values, dtype=float) - mean) ** 2))
        if not self.count:
            self.count, self.mean, self.m2 = n, mean, m2
            return
        total = self.count + n
        delta = mean - self.mean
        self.mean += delta * n / total
        self.m2 += m2 + delta**2 * self.count * n / total
        self.count = total

    @property
    def std(self) -> float:
        """Population standard deviation, in the unit of the values (e.g. °C; 0 before any)."""
        return math.sqrt(self.m2 / self.count) if self.count else 0.0


@dataclass
class _Summary:
    """What the evidence keeps of one step's DAQ log: the temperature's moments, the first
    :data:`LINE_SAMPLES` samples of each sensor channel (V), the length and the rate (Hz)."""

    temperature: Moments | None
    heads: dict[str, np.ndarray]
    samples: int
    sample_rate_hz: float


def _summary_of_log(daq: Any, channels: list[str]) -> _Summary:
    """The summary of a whole DAQ log (an in-memory or sine step)."""
    temps = daq.channels.get(_TEMPERATURE)
    moments = None
    if temps is not None:
        moments = Moments()
        moments.add(temps)
    heads = {ch: daq.channels[ch][:LINE_SAMPLES] for ch in channels if ch in daq.channels}
    return _Summary(moments, heads, len(daq), float(daq.sample_rate_hz))


def _streamed_summary(steps: Any, index: int, channels: list[str]) -> _Summary:
    """The summary of a recorded DAQ log read piece by piece (only the temperature and
    ``channels``): an hours-long static record costs one block and the heads, not 115 MB
    per channel."""
    moments: Moments | None = None
    parts: dict[str, list[np.ndarray]] = {}
    samples, rate = 0, 0.0
    for piece in steps.pieces(index, "daq", [*channels, _TEMPERATURE]):
        rate = float(piece.sample_rate_hz)
        if _TEMPERATURE in piece.channels:
            moments = moments or Moments()
            moments.add(piece[_TEMPERATURE])
        take = min(len(piece), LINE_SAMPLES - samples)
        for ch in channels:
            if ch in piece.channels:
                parts.setdefault(ch, [])
                if take > 0:
                    parts[ch].append(piece[ch][:take])
        samples += len(piece)
    heads = {ch: np.concatenate(p) if p else np.empty(0) for ch, p in parts.items()}
    return _Summary(moments, heads, samples, rate)


def _sine_channels(step: Any, channels: list[str]) -> dict[str, list[str]]:
    """The channels the evidence reads of a sine step, by source: the moving axis' position and
    acceleration estimate, the DAQ's sensor ``channels`` and temperature."""
    return {"daq": [*channels, _TEMPERATURE, "trigger"],
            "table": [f"{step.axis}_position_deg", f"{step.axis}_accel_dps2"]}


def _record(data: Any, index: int, channels: list[str]) -> Any:
    """Sine step ``index`` with only the channels the evidence reads (a recording's lazy
    steps, :func:`_sine_channels`). An in-memory dataset's step is read as it is."""
    from aatest.recording.dataset import LazySteps

    steps = data.steps
    if not isinstance(steps, LazySteps):
        return steps[index]
    return steps.partial(index, _sine_channels(steps.planned[index], channels))


@dataclass(frozen=True)
class _SineEvidence:
    """What the evidence keeps of one sine step (a few numbers, no samples)."""

    temperature: Moments | None
    motion: MotionEvidence | None
    bin_noise: BinNoise | None


def _sine_evidence(record: Any, channels: list[str]) -> _SineEvidence:
    """Temperature moments, motion and local noise of one decoded sine step."""
    step = record.step
    summary = _summary_of_log(record.daq, [])
    position = record.table.channels.get(f"{step.axis}_position_deg")
    cycles = getattr(step, "cycles", None)
    amplitude = getattr(step, "amplitude_deg", None) or 0.0
    if position is None or not cycles:
        return _SineEvidence(summary.temperature, None, None)
    return _SineEvidence(
        summary.temperature,
        _motion(np.asarray(position, dtype=float), int(cycles), float(amplitude)),
        _bin_noise(record, int(cycles), channels))


#: the name the evidence's per-step reduction is watched under (:func:`watch`)
_WATCH = "uncertainty.evidence"


def watch(data: Any) -> None:
    """Measure each sine step's evidence when an analysis first decodes that step.

    Why: the analyses (the sync pass first) already decode every sine step, and the fixed part
    of a decode costs more than the few channels added here; :func:`gather` then reads the
    results instead of decoding every sine step again (values identical: the same channels,
    the same reductions). Only a recording's lazy steps are watched; nothing else changes.

    Parameters
    ----------
    data
        The :class:`aatest.recording.dataset.Dataset` the analyses are about to read.
    """
    from aatest.recording.dataset import LazySteps, StepWatch

    steps = getattr(data, "steps", None)
    if not isinstance(steps, LazySteps):
        return
    channels = [s.channel for s in data.sensors]
    steps.watch(_WATCH, StepWatch(
        channels=lambda step: _sine_channels(step, channels),
        applies=lambda step: step.kind == "sine",
        reduce=lambda record: _sine_evidence(record, channels)))


def _sine_of(data: Any, index: int, channels: list[str]) -> _SineEvidence:
    """The evidence of sine step ``index``: measured while an analysis decoded it, else now."""
    from aatest.recording.dataset import LazySteps

    if isinstance(data.steps, LazySteps):
        try:
            found: _SineEvidence = data.steps.watched(_WATCH, index)
        except KeyError:
            pass
        else:
            return found
    return _sine_evidence(_record(data, index, channels), channels)


def gather(data: Any) -> Evidence:
    """Measure the motion of every coherent sine record and the logged temperatures.

    One step at a time, and of it only the channels read here: a recorded sine step decoded
    partially (:func:`_record`; or already measured while an analysis decoded it,
    :func:`watch`), any other recorded step read piece by piece (:func:`_streamed_summary`),
    so memory does not grow with the steps or the record length.

    Parameters
    ----------
    data
        The :class:`aatest.recording.dataset.Dataset` the analyses ran on (None: nothing measured).
    """
    from aatest.recording.dataset import LazySteps

    if data is None:
        return Evidence()
    motion: dict[str, MotionEvidence] = {}
    temperature: dict[str, TemperatureEvidence] = {}
    bin_noise: dict[str, BinNoise] = {}
    lines: dict[str, dict[str, StaticLine]] = {}
    channels = [s.channel for s in data.sensors]
    present = data.metadata.get("temperature_present", True)
    for index, step in enumerate(data.planned):
        sine = _sine_of(data, index, channels) if step.kind == "sine" else None
        if sine is not None:
            moments = sine.temperature
        elif isinstance(data.steps, LazySteps):
            summary = _streamed_summary(data.steps, index, channels if step.kind == "static"
                                        else [])
            moments = summary.temperature
        else:
            summary = _summary_of_log(data.steps[index].daq,
                                      channels if step.kind == "static" else [])
            moments = summary.temperature
        if present and moments is not None and moments.count:
            temperature[step.id] = TemperatureEvidence(moments.mean, moments.std)
        if step.kind == "static":
            found = {ch: line_of_head(head, summary.samples, summary.sample_rate_hz)
                     for ch, head in summary.heads.items()}
            lines[step.id] = {ch: line for ch, line in found.items() if line is not None}
        if sine is not None and sine.motion is not None:
            motion[step.id] = sine.motion
        if sine is not None and sine.bin_noise is not None:
            bin_noise[step.id] = sine.bin_noise
    return Evidence(motion, temperature, recording=True, bin_noise=bin_noise,
                    static_lines=lines)
