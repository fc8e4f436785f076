"""Stepped-sine frequency response at the excitation DFT bin (docs/method.md §4.4).

Every sine step along a sensor's axis gives one FRF point: the complex fundamentals of the
table's acceleration estimate (input, °/s²) and of the sensor output (V) on the synchronised
grid, their ratio (gain dB re 1 V/(°/s²), phase, phase delay), and for both signals the THD
(harmonics 2–6 over the fundamental) and SNR (fundamental, or the first six harmonics, over the
power in every other non-DC bin). Records are coherent (an integer number of cycles), so no
window is needed; a non-coherent record is cut to whole cycles and flagged. ``thd``/``snr``
listed in a procedure are aliases of this analysis.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from aatest.engine.dataset import Dataset, SensorInfo
from aatest.engine.interfaces import AnalysisContext, AnalysisOutput
from aatest.plugins.analysis._common import (
    INPUT_ACCEL_CHANNELS,
    group_of,
    input_accel_dps2,
    is_excited,
    new_figure,
    options_of,
    select,
    steps_of,
    to_svg,
    whole_cycles,
)
from aatest.plugins.analysis.sync import SyncedSteps, SyncedWatch, watch_synced
from aatest.results.frf import FrfResult
from aatest.sync.freeze_pulse import SyncedStep

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
        return float(10.0 * np.log10(signal_power / max(self.noise_power, 1e-300)))

    @property
    def u_relative(self) -> float:
        """Standard uncertainty of the fundamental's amplitude, relative (also phase, rad)."""
        return float(np.sqrt(self.noise_bin_power / 2.0) / self.amplitudes[0])


def analyse_tone(x: np.ndarray, frequency_hz: float, fs_hz: float,
                 harmonics: int = HARMONICS) -> Tone:
    """Fundamental, harmonics 1..``harmonics`` and noise of a record at a known excitation
    frequency (the THD sums harmonics 2..``harmonics``)."""
    n, cycles = whole_cycles(x.size, frequency_hz, fs_hz)
    seg = np.asarray(x[:n], dtype=np.float64)
    spec = np.fft.rfft(seg - seg.mean()) * 2.0 / n
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
    noise = np.abs(spec[mask]) ** 2
    return Tone(fundamental=complex(spec[cycles]), amplitudes=amps,
                noise_power=float(np.sum(noise)) / 2.0,
                noise_bin_power=float(np.mean(noise)) if noise.size else 0.0, coherent=coherent,
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


def frf_point(synced: SyncedStep, sensor: SensorInfo, harmonics: int = HARMONICS
              ) -> dict[str, Any]:
    """One FRF point of a sensor from one sine step (contract keys and more).

    ``snr6_db``/``table_snr6_db`` keep their names but count ``harmonics`` harmonics.
    """
    step, fs = synced.step, synced.sample_rate_hz
    f0 = float(step.frequency_hz or 0.0)
    table = analyse_tone(input_accel_dps2(synced, sensor.axis), f0, fs, harmonics)
    sensor_tone = analyse_tone(synced.daq[sensor.channel], f0, fs, harmonics)
    u_local = local_ratio_noise_rel(table, sensor_tone)
    ratio = sensor_tone.fundamental / table.fundamental
    phase_rad = float(np.angle(ratio))
    u_rel = float(np.hypot(table.u_relative, sensor_tone.u_relative))
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
        "u_gain_db": 20 / np.log(10) * u_rel, "u_phase_deg": float(np.degrees(u_rel)),
        "u_delay_s": u_rel / (2 * np.pi * f0),
        "coherent": table.coherent, "group": group_of(step), "step": step.id,
        "sample_rate_hz": fs, "u_local_rel": u_local,
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
    fig.tight_layout()
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
            _watch_name(sensor, harmonics), point)
    else:
        points = [point(s) for s in select(steps, lambda p: is_excited(p, sensor))]
    points.sort(key=lambda p: (p["group"], p["frequency_hz"]))
    unwrap_phases(points)
    return points


def _watch_name(sensor: SensorInfo, harmonics: int) -> str:
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

        watch_synced(data, _watch_name(sensor, harmonics), SyncedWatch(
            {"table": INPUT_ACCEL_CHANNELS, "daq": (sensor.channel,)}, excited, point))


class FrfAnalysis:
    """Stepped-sine FRF, THD and SNR of every sensor and of the table (per group)."""

    key: ClassVar[str] = "frf"
    #: procedure names of sub-results this plugin computes (``analysis: [thd, snr]``)
    aliases: ClassVar[tuple[str, ...]] = ("thd", "snr")
    requires: ClassVar[tuple[str, ...]] = ("sync",)
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
        figures: dict[str, str] = {}
        for sensor in data.sensors:
            points = channel_points(steps, sensor, harmonics)
            if points:
                values[sensor.channel] = points
                figures[f"bode_{sensor.channel}"] = bode_figure(points, f"FRF {sensor.channel}")
        return AnalysisOutput(FrfResult.model_validate(values), figures)
