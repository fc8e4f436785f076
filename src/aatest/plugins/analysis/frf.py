"""Stepped-sine frequency response at the excitation frequency (docs/method.md §4.4).

Every sine step along a sensor's axis gives one FRF point: the ratio of the complex
fundamentals of the sensor output (V) and of the table's acceleration estimate (input, °/s²)
on the synchronised grid (gain dB re 1 V/(°/s²), phase, phase delay), and for both signals
the THD (harmonics 2–6 over the fundamental) and SNR (fundamental, or the first six
harmonics, over the power in every other non-DC bin) from the record's DFT.

The ratio is the mean over Hann-weighted, 50 %-overlapping segments of whole cycles
(:func:`segmented_ratio`), not the record's single rectangular-window bin: the segments do not
let the motor band leak into the fundamental, and their spread measures how much the ratio
varies within the record (Type A, ``u_segments_*``). The neighbour-bin noise of the record's
ratio (``u_local_rel``) is kept beside it; the uncertainty stage takes the larger. A
non-coherent record is cut to whole cycles for the DFT metrics and flagged. ``thd``/``snr``
listed in a procedure are aliases of this analysis.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Hashable, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from pydantic import BaseModel, ConfigDict, Field
from scipy import linalg

from aatest.clocksync.freeze_pulse import SyncedStep
from aatest.engine.interfaces import AnalysisContext, AnalysisOutput
from aatest.engine.requirements import Requirement
from aatest.numerics import TINY
from aatest.plugins.analysis import needs
from aatest.plugins.analysis._common import (
    INPUT_ACCEL_CHANNELS,
    group_of,
    input_accel_channels,
    input_accel_dps2,
    is_excited,
    options_of,
    select,
    steps_of,
    whole_cycles,
)
from aatest.plugins.analysis.step_spectra import centred_rfft, input_key, output_key
from aatest.plugins.analysis.sync import SyncedSteps, SyncedWatch, watch_synced
from aatest.presentation.figures import (
    Drawing,
    DrawnFigures,
    drawn,
    frequency_axis,
    new_figure,
    tight_layout,
    to_svg,
)
from aatest.recording.dataset import Dataset, SensorInfo
from aatest.results.frf import FrfResult

HARMONICS = 6
_COHERENCE_TOL_CYCLES = 1e-3
#: bins either side of the fundamental whose ratio noise estimates the noise at it
NEAR_BINS = np.arange(3, 41)


@dataclass(frozen=True)
class Tone:
    """Spectral summary of one sinusoidal record at its excitation frequency."""

    fundamental: complex
    amplitudes: np.ndarray  # one-sided peak amplitudes of harmonics 1..6
    noise_power: float  # mean-square of the non-harmonic, non-DC content
    noise_bin_power: float  # mean one-sided |X|² per noise bin (peak-amplitude² units)
    coherent: bool
    #: one-sided spectrum of the whole cycles analysed (peak amplitudes), and the fundamental's
    #: bin in it: what :func:`local_ratio_noise_rel` compares, without a second FFT
    spectrum: np.ndarray
    cycles: int

    @property
    def thd(self) -> float:
        return float(np.sqrt(np.sum(self.amplitudes[1:] ** 2)) / self.amplitudes[0])

    def snr_db(self, harmonics: int = 1) -> float:
        signal_power = float(np.sum(self.amplitudes[:harmonics] ** 2)) / 2.0
        return float(10.0 * np.log10(signal_power / max(self.noise_power, TINY)))

    @property
    def u_relative(self) -> float:
        """Standard uncertainty of the fundamental's amplitude, relative (also phase, rad)."""
        return float(np.sqrt(self.noise_bin_power / 2.0) / self.amplitudes[0])


def analyse_tone(x: np.ndarray, frequency_hz: float, fs_hz: float,
                 harmonics: int = HARMONICS, key: Hashable | None = None) -> Tone:
    """Fundamental, harmonics 1..``harmonics`` and noise of a record at a known excitation
    frequency (the THD sums harmonics 2..``harmonics``).

    ``key`` names the record for :func:`~aatest.plugins.analysis.step_spectra.centred_rfft`:
    inside its ``shared`` scope the record's DFT is made once for every reduction of it.
    """
    n, cycles = whole_cycles(x.size, frequency_hz, fs_hz)
    spec = centred_rfft(x[:n], key) * 2.0
    spec /= n
    coherent = abs(frequency_hz * n / fs_hz - round(frequency_hz * n / fs_hz)) < \
        _COHERENCE_TOL_CYCLES
    bins = cycles * np.arange(1, harmonics + 1)
    bins = bins[bins < spec.size]
    mask = np.ones(spec.size, dtype=bool)
    mask[0] = False
    guard = 0 if coherent else 2  # leakage of a cut record stays within ±2 bins
    for b in bins:
        mask[max(b - guard, 1):b + guard + 1] = False
    amps = np.zeros(harmonics)
    amps[:bins.size] = np.abs(spec[bins])
    power = np.abs(spec)  # |X|² of every bin, then the noise bins': the values and the
    power *= power  # sums of squaring the noise bins alone, without a copy of them complex
    noise = power[mask]
    total = float(np.sum(noise))
    return Tone(fundamental=complex(spec[cycles]), amplitudes=amps, noise_power=total / 2.0,
                noise_bin_power=total / noise.size if noise.size else 0.0, coherent=coherent,
                spectrum=spec, cycles=cycles)


def local_ratio_noise_rel(reference: Tone, output: Tone) -> float | None:
    """Standard uncertainty of the fundamental ratio Y₁/X₁, relative (= phase, rad), from the
    bins next to it (``reference`` X and ``output`` Y: the tones of one record).

    At a bin k near the fundamental, D_k = Y_k/Y₁ − X_k/X₁ is what the ratio would pick up if
    that bin's content sat at the fundamental: independent noise of output and reference adds
    in quadrature, content common to both (non-commanded motion the sensor follows) cancels as
    it does at the fundamental, and the leakage of a far line (the motor band) enters with the
    sensor's response at the line — added or cancelled as at the fundamental. u = √(mean
    |D_k|²/2) over the bins 3–40 away (harmonic bins excluded): half the power is tangential.
    Coherent records only (the fundamental's own leakage would dominate otherwise): None.
    """
    if not (reference.coherent and output.coherent):
        return None
    spec_x, spec_y, cycles = reference.spectrum, output.spectrum, reference.cycles
    near = np.concatenate([cycles - NEAR_BINS, cycles + NEAR_BINS])
    near = near[(near > 0) & (near < spec_x.size) & (near % cycles != 0)]
    if near.size == 0 or spec_x[cycles] == 0 or spec_y[cycles] == 0:
        return None
    d = spec_y[near] / spec_y[cycles] - spec_x[near] / spec_x[cycles]
    return float(np.sqrt(np.mean(np.abs(d) ** 2) / 2.0))


#: segments the record is cut into (50 % overlap): a Type A spread with ≈13 degrees of freedom
#: (records of fewer than 16 cycles get fewer: the bench's 8-cycle record 7, ν ≈ 5.7)
TARGET_SEGMENTS = 15
#: one-cycle segments were measured biased (+0.025° in phase at 0.98 Hz on a twin rig, where
#: segments of two, four and eight cycles and the whole record's bin agreed within 0.006°;
#: the cause was not found): at least two cycles per segment
MIN_CYCLES_PER_SEGMENT = 2
#: a spread needs two segments
_MIN_SEGMENTS = 2


@dataclass(frozen=True)
class SegmentedRatio:
    """The FRF ratio Y/X as the mean over Hann-weighted, 50 %-overlapping segments.

    ``u_gain_rel`` (relative) and ``u_phase_rad`` are the Type A standard uncertainties of the
    mean from the segments' spread (radial and tangential part apart), ``dof`` their effective
    degrees of freedom.
    """

    ratio: complex
    u_gain_rel: float | None
    u_phase_rad: float | None
    dof: float | None
    segments: int
    cycles_per_segment: int


def segment_layout(n_samples: int, frequency_hz: float, fs_hz: float) -> tuple[int, int, int]:
    """(length, hop, count) of the segments: whole cycles each (rounded to a sample), hop
    half a segment, ≈ :data:`TARGET_SEGMENTS` of them (fewer when a record holds fewer than
    ``(TARGET_SEGMENTS + 1)·MIN_CYCLES_PER_SEGMENT / 2`` cycles)."""
    period = fs_hz / frequency_hz
    cycles = max(MIN_CYCLES_PER_SEGMENT,
                 round(2.0 * n_samples / period / (TARGET_SEGMENTS + 1)))
    length = min(round(cycles * period), n_samples)
    hop = max(length // 2, 1)
    return length, hop, 1 + (n_samples - length) // hop


def _periodic_hann(length: int) -> np.ndarray:
    """Hann weights of period ``length`` (0 at the first sample): over a segment of whole
    periods every harmonic k·m (m cycles per segment) leaks only into bins k·m ± 1, never
    into the fundamental's bin m unless it is fitted (k = 2, m = 1)."""
    return 0.5 - 0.5 * np.cos(2.0 * np.pi * np.arange(length) / length)


#: a Gram matrix of the segment fit conditioned worse than this is solved by the SVD instead
#: (the well-laid-out design's is ≈ 2, see :func:`_segment_projector`)
_GRAM_MAX_CONDITION = 1e6


@functools.lru_cache(maxsize=32)
def _segment_projector(length: int, frequency_hz: float, fs_hz: float, harmonics: int
                       ) -> np.ndarray:
    """(length, 2) weights whose products with a segment are the fundamental's cosine and
    sine coefficients of its Hann-weighted least-squares fit (:func:`_fit_fundamentals`).

    The fit's normal equations G·c = Dᵀ·W·x (D: columns 1, cos kωτ, sin kωτ; W: the periodic
    Hann weights) are solved once for the two fundamental rows, with the weights folded in:
    coefficients = x·(W·D·G⁻¹)[:, fundamental]. Why the normal equations are sound here: the
    columns are sines and cosines of whole cycles per segment (two at least) on a uniform
    grid, which the Hann weights leave orthogonal but for the rounding of the segment to a
    sample, so G is diagonal to that rounding (ΣW/2 for cos² and sin², ΣW for the mean) and
    its condition number is ≈ 2 (measured over the stepped sine's layouts: 2.0000 to 2.23 with
    a harmonic next to Nyquist). Squaring it costs no digits, and a Cholesky factor of the
    13 × 13 G takes ≈ a tenth of the time of the SVD of the length × 13 design. A G worse
    than :data:`_GRAM_MAX_CONDITION` (a harmonic at Nyquist, whose sine column vanishes)
    falls back to the pseudo-inverse.

    Why cached: it depends only on the segment layout, and a stepped sine repeats each
    frequency in every acceleration group; the reference and the output of a step share it
    (the array is read-only).
    """
    omega_tau = 2.0 * np.pi * frequency_hz / fs_hz * np.arange(length)
    k = np.arange(1, harmonics + 1)
    k = k[k * frequency_hz < fs_hz / 2.0]
    angles = np.outer(omega_tau, k)
    design = _design(angles)
    weights = _periodic_hann(length)
    weighted = design * weights[:, None]
    gram = weighted.T @ design
    fundamental = [1, 1 + int(k.size)]
    if np.linalg.cond(gram) <= _GRAM_MAX_CONDITION:
        picked = linalg.cho_solve(linalg.cho_factor(gram), np.eye(gram.shape[0])[:, fundamental])
        projector = weighted @ picked
    else:
        root_w = np.sqrt(weights)
        projector = (np.linalg.pinv(design * root_w[:, None])[fundamental] * root_w).T
    projector = np.ascontiguousarray(projector)
    projector.flags.writeable = False
    return projector


def _design(angles: np.ndarray) -> np.ndarray:
    """The columns 1, cos(angles), sin(angles) of the segment fit, each written in place.

    Why not ``column_stack``: the cosines and sines of a cached layout's ≈ 16 000 × 6 angles
    are the cost that matters (≈ 1.8 ms); stacking them made three more arrays and copied
    them, another ≈ 1.8 ms (page faults of fresh megabytes included) at each of the stepped
    sine's 28 layouts. The values are the same ufuncs' of the same angles.
    """
    harmonics = angles.shape[1]
    design = np.empty((angles.shape[0], 1 + 2 * harmonics))
    design[:, 0] = 1.0
    np.cos(angles, out=design[:, 1:1 + harmonics])
    np.sin(angles, out=design[:, 1 + harmonics:])
    return design


def _fit_fundamentals(segments: np.ndarray, frequency_hz: float, fs_hz: float,
                      harmonics: int) -> np.ndarray:
    """Complex fundamental of every row of ``segments`` (rows: segments), x ≈ Re(c·e^{jωτ}),
    by Hann-weighted least squares of the mean, the fundamental and harmonics 2..H below
    Nyquist (τ: time from the segment's start; the phase reference cancels in a ratio).

    The fit removes every periodic component exactly however many samples a period holds,
    and the Hann weights make non-harmonic content (the motor band) leak as 1/Δ³. Only the
    fundamental's two coefficients are formed (:func:`_segment_projector`).
    """
    projector = _segment_projector(segments.shape[1], frequency_hz, fs_hz, harmonics)
    coef = segments @ projector
    return np.asarray(coef[:, 0] - 1j * coef[:, 1])


def _segments(record: np.ndarray, length: int, hop: int, count: int) -> np.ndarray:
    """The ``count`` segments of ``length`` samples, ``hop`` apart, as rows: a strided view
    (the values of a gathered copy, without building an index of every sample)."""
    windows = np.lib.stride_tricks.sliding_window_view(
        np.asarray(record, dtype=np.float64), length)
    return windows[:(count - 1) * hop + 1:hop]


@functools.lru_cache(maxsize=32)
def _overlap_correlation(length: int, hop: int) -> float:
    """Correlation of white noise's fundamental estimates in two segments ``hop`` apart
    (Σ w[n]·w[n+hop] / Σ w², Hann w: 1/6 at 50 % overlap; cached like the layout's
    projector: a stepped sine repeats each layout in every group)."""
    w = _periodic_hann(length)
    return float(np.dot(w[hop:], w[:length - hop]) / np.dot(w, w)) if hop < length else 0.0


def segmented_ratio(reference: np.ndarray, output: np.ndarray, frequency_hz: float,
                    fs_hz: float, harmonics: int = HARMONICS) -> SegmentedRatio:
    """FRF ratio output/reference at ``frequency_hz`` as the mean of per-segment ratios.

    Why segments: one rectangular-window bin over the record keeps ≈0.004° of the motor
    band's leakage at 4 Hz, and it cannot show how much the fundamental varies from cycle to
    cycle — the motor band dithers the sensor's hysteresis differently in every cycle, so one
    record's ratio scatters about its expectation (≈0.006° at 1 Hz) by more than its noise
    floor says. The mean of K Hann-weighted segments (whole cycles each, 50 % overlap) has
    neither leakage problem, and the segments' spread measures all of that scatter (Type A).

    Uncertainty: s² of the segment ratios' relative deviations, radial (gain) and tangential
    (phase) apart; adjacent segments overlap, so for a white disturbance their estimates
    correlate by r (:func:`_overlap_correlation`). Then u² = s²/K·(1 + 2r(K−1)/K)/(1 − 2r/K)
    (the variance of the mean, s² being biased low by the correlation), with
    ν = (K − 1)/(1 + 2r²) degrees of freedom (Bartlett's correction of a sample variance).
    A record too short for two segments gives None for u and ν.
    """
    n = min(reference.size, output.size)
    length, hop, count = segment_layout(n, frequency_hz, fs_hz)
    x = _fit_fundamentals(_segments(reference, length, hop, count), frequency_hz, fs_hz,
                          harmonics)
    y = _fit_fundamentals(_segments(output, length, hop, count), frequency_hz, fs_hz,
                          harmonics)
    ratios = y / x
    mean = complex(np.mean(ratios))
    cycles = max(1, round(length * frequency_hz / fs_hz))
    if count < _MIN_SEGMENTS:
        return SegmentedRatio(mean, None, None, None, count, cycles)
    rel = ratios / mean - 1.0
    r = _overlap_correlation(length, hop)
    inflation = (1.0 + 2.0 * r * (count - 1) / count) / (1.0 - 2.0 * r / count) / count
    u_gain = math.sqrt(float(np.var(rel.real, ddof=1)) * inflation)
    u_phase = math.sqrt(float(np.var(rel.imag, ddof=1)) * inflation)
    return SegmentedRatio(mean, u_gain, u_phase, (count - 1) / (1.0 + 2.0 * r**2), count,
                          cycles)


def stated_ratio_u(table: Tone, output: Tone, u_local: float | None,
                   segmented: SegmentedRatio) -> tuple[float, float]:
    """(relative gain, phase rad) standard uncertainty the FRF point states for its ratio.

    What sits at the fundamental: the larger of the neighbour-bin noise of the ratio
    (:func:`local_ratio_noise_rel`) and the segments' spread (Type A, gain and phase apart),
    as the uncertainty stage takes them. Only when neither exists (a non-coherent record of
    fewer than three cycles) the white-noise form 1/√(N·SNR) of each tone: it spreads all
    non-harmonic power over every bin, so the 30–40 Hz motor band, which does not reach a
    coherent fundamental, inflates it (on the twin at 1 Hz: 0.13° against 0.007° at the bin).
    """
    local = [] if u_local is None else [u_local]
    gain = local + [u for u in (segmented.u_gain_rel,) if u is not None and math.isfinite(u)]
    phase = local + [u for u in (segmented.u_phase_rad,) if u is not None and math.isfinite(u)]
    white = float(np.hypot(table.u_relative, output.u_relative))
    return (max(gain) if gain else white), (max(phase) if phase else white)


def frf_point(synced: SyncedStep, sensor: SensorInfo, harmonics: int = HARMONICS
              ) -> dict[str, Any]:
    """One FRF point of a sensor from one sine step (contract keys and more).

    ``snr6_db``/``table_snr6_db`` keep their names but count ``harmonics`` harmonics.
    """
    step, fs = synced.step, synced.sample_rate_hz
    f0 = float(step.frequency_hz or 0.0)
    reference, output = input_accel_dps2(synced, sensor.axis), synced.daq[sensor.channel]
    # the same records' DFTs as the cross-correlation's (tf_xcorr), made once per step
    table = analyse_tone(reference, f0, fs, harmonics, input_key(synced, sensor))
    sensor_tone = analyse_tone(output, f0, fs, harmonics, output_key(synced, sensor))
    u_local = local_ratio_noise_rel(table, sensor_tone)
    segmented = segmented_ratio(reference, output, f0, fs, harmonics)
    # a record of fewer than three cycles has no two segments: its whole-record bin stands
    ratio = (segmented.ratio if segmented.segments >= _MIN_SEGMENTS
             else sensor_tone.fundamental / table.fundamental)
    phase_rad = float(np.angle(ratio))
    u_gain_rel, u_phase_rad = stated_ratio_u(table, sensor_tone, u_local, segmented)
    delay_s = -phase_rad / (2 * np.pi * f0)
    return {
        "frequency_hz": f0, "accel_dps2": float(step.accel_dps2 or abs(table.fundamental)),
        "gain_db": float(20 * np.log10(abs(ratio))), "phase_deg": float(np.degrees(phase_rad)),
        "delay_s": delay_s, "delay_samples": delay_s * fs,
        "thd": sensor_tone.thd, "snr_db": sensor_tone.snr_db(1),
        "snr6_db": sensor_tone.snr_db(harmonics),
        "table_thd": table.thd, "table_snr_db": table.snr_db(1),
        "table_snr6_db": table.snr_db(harmonics),
        "measured_accel_dps2": abs(table.fundamental),
        "gain_v_per_dps2": abs(ratio), "re": ratio.real, "im": ratio.imag,
        "u_gain_db": 20 / np.log(10) * u_gain_rel, "u_phase_deg": float(np.degrees(u_phase_rad)),
        "u_delay_s": u_phase_rad / (2 * np.pi * f0),
        "coherent": table.coherent, "group": group_of(step), "step": step.id,
        "sample_rate_hz": fs, "u_local_rel": u_local,
        "u_segments_gain_rel": segmented.u_gain_rel,
        "u_segments_phase_rad": segmented.u_phase_rad, "segments_dof": segmented.dof,
        "segments": segmented.segments, "cycles_per_segment": segmented.cycles_per_segment,
    }


def unwrap_phases(points: list[dict[str, Any]]) -> None:
    """Unwrap ``phase_deg`` along frequency within each group (delays follow)."""
    for group in {p["group"] for p in points}:
        rows = sorted((p for p in points if p["group"] == group), key=lambda p: p["frequency_hz"])
        phases = np.degrees(np.unwrap(np.radians([p["phase_deg"] for p in rows])))
        for p, ph in zip(rows, phases, strict=True):
            p["phase_deg"] = float(ph)
            p["delay_s"] = float(-np.radians(ph) / (2 * np.pi * p["frequency_hz"]))
            p["delay_samples"] = p["delay_s"] * p["sample_rate_hz"]


def bode_figure(points: list[dict[str, Any]], title: str) -> str:
    """Gain and phase against frequency, one line per test group."""
    fig, ax = new_figure(2, height_in=2.4)
    for group in sorted({p["group"] for p in points}):
        rows = sorted((p for p in points if p["group"] == group), key=lambda p: p["frequency_hz"])
        f = [p["frequency_hz"] for p in rows]
        ax[0, 0].semilogx(f, [p["gain_db"] for p in rows], "o-", ms=3, label=group)
        ax[1, 0].semilogx(f, [p["phase_deg"] for p in rows], "o-", ms=3)
    ax[0, 0].set(ylabel="gain / dB re V/(°/s²)", title=title)
    ax[1, 0].set(xlabel="frequency / Hz", ylabel="phase / °")
    ax[0, 0].legend(fontsize=6)
    frequency_axis(ax[0, 0], ax[1, 0])
    tight_layout(fig)
    return to_svg(fig)


class FrfOptions(BaseModel):
    """Harmonics counted in the THD (2..H) and the harmonic SNR (1..H)."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    harmonics: int = Field(HARMONICS, ge=2, le=50, description="highest harmonic H")


def channel_points(steps: Sequence[SyncedStep], sensor: SensorInfo, harmonics: int = HARMONICS
                   ) -> list[dict[str, Any]]:
    """The FRF points of one sensor, sorted by group and frequency, phases unwrapped.

    On the lazy steps of ``sync`` only the table's acceleration channels and this sensor's are
    decoded and synchronised (:data:`INPUT_ACCEL_CHANNELS`): the same values as whole steps, at
    about half the decoding cost per step.
    """
    def point(synced: SyncedStep) -> dict[str, Any]:
        return frf_point(synced, sensor, harmonics)

    if isinstance(steps, SyncedSteps):  # the points the sync pass made, else from the steps
        steps = steps.only(table=INPUT_ACCEL_CHANNELS, daq=(sensor.channel,))
        points = steps.where(lambda p: is_excited(p, sensor)).reduced(
            point_watch_name(sensor, harmonics), point)
    else:
        points = [point(s) for s in select(steps, lambda p: is_excited(p, sensor))]
    points.sort(key=lambda p: (p["group"], p["frequency_hz"]))
    unwrap_phases(points)
    return points


def point_watch_name(sensor: SensorInfo, harmonics: int) -> str:
    """The name of the synced watch making ``sensor``'s per-step FRF points."""
    return f"frf.point:{sensor.channel}:{harmonics}"


def watch_points(data: Dataset, harmonics: int = HARMONICS) -> None:
    """Have the sync pass make every sensor's FRF points as it decodes the sine steps (read
    back by :func:`channel_points`): a recorded step is then decoded once, not once more here.
    """
    for sensor in data.sensors:
        def excited(p: Any, sensor: SensorInfo = sensor) -> bool:
            return bool(p.kind == "sine" and is_excited(p, sensor))

        def point(synced: SyncedStep, sensor: SensorInfo = sensor) -> dict[str, Any]:
            return frf_point(synced, sensor, harmonics)

        def channels(p: Any, sensor: SensorInfo = sensor) -> dict[str, tuple[str, ...]]:
            return {"table": input_accel_channels(p), "daq": (sensor.channel,)}

        watch_synced(data, point_watch_name(sensor, harmonics),
                     SyncedWatch(channels, excited, point))


class FrfAnalysis:
    """Stepped-sine FRF, THD and SNR of every sensor and of the table (per group)."""

    key: ClassVar[str] = "frf"
    #: procedure names of sub-results this plugin computes (``analysis: [thd, snr]``)
    aliases: ClassVar[tuple[str, ...]] = ("thd", "snr")
    requires: ClassVar[tuple[str, ...]] = ("sync",)
    #: what the plan must hold (checked by ``validate``; aatest.engine.requirements)
    requirements: ClassVar[tuple[Requirement, ...]] = needs.SINE
    #: the acceptance quantities it produces (judged when it is listed)
    judges: ClassVar[tuple[str, ...]] = ()
    Options: ClassVar[type[FrfOptions]] = FrfOptions
    Result: ClassVar[type[FrfResult]] = FrfResult

    def applies_to(self, data: Dataset) -> bool:
        return any(p.kind == "sine" for p in data.planned)

    def watch_steps(self, data: Dataset, options: BaseModel) -> None:
        """Register the FRF points with the sync pass (:func:`watch_points`)."""
        chosen = options if isinstance(options, FrfOptions) else \
            FrfOptions.model_validate(options.model_dump())
        harmonics = chosen.harmonics
        watch_points(data, harmonics)

    def run(self, data: Dataset, context: AnalysisContext) -> AnalysisOutput[FrfResult]:
        steps = steps_of(context, "sine")
        harmonics = options_of(context, FrfOptions).harmonics
        values: dict[str, list[dict[str, Any]]] = {}
        figures: dict[str, Drawing] = {}
        for sensor in data.sensors:
            points = channel_points(steps, sensor, harmonics)
            if points:
                values[sensor.channel] = points
                figures[f"bode_{sensor.channel}"] = drawn(bode_figure, points,
                                                          f"FRF {sensor.channel}")
        return AnalysisOutput(FrfResult.model_validate(values), DrawnFigures(figures))
