"""Generic, data-driven extensions for structure the effect vocabulary cannot name.

After the named effects are selected, the residual may still hold structure. Each proposal
here reads the residual, describes one kind of structure physically and returns the design
columns of a generic extension for it (docs/interfaces.md §4 ``unexplained``):

* ``static_nonlinearity`` — output ∝ α² (even order: the same sign for +α and −α, which a
  cubic, odd in α, cannot be);
* ``asymmetry`` — output ∝ |α|: a scale factor that differs for α > 0 and α < 0;
* ``spectral_line`` — a sine at one frequency in every step (phase free per step), compared
  with the table's position log: a line the table does not show is electrical, not motion;
* ``trend`` — bias and scale drifting linearly with elapsed session time (steps taken back
  to back; a step's own duration is known, the pauses between steps are not);
* ``step_change`` — the bias jumps once inside one record (the largest CUSUM change point).

Columns are per step, on the record grid, in volts per unit coefficient; the selection in
:mod:`aatest.diagnose.unexplained` fits them jointly with the named model on held-out blocks.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import optimize, signal

from aatest.diagnose.periodogram import dft_at, is_uniform, lomb_scargle_at
from aatest.diagnose.replay import StepReplay
from aatest.numerics import TINY

#: a residual line stands this far above the median of the step-averaged residual spectrum
LINE_SNR = 12.0
#: spectral lines proposed per pass, strongest first
MAX_LINES = 3
#: a line's frequency is estimated to this (Hz): a 2 mHz error on a 10 mV line over a 4 s
#: record leaves a 0.3 mV residual (1.07× a 1 mV floor); 0.1 mHz leaves 15 µV
LINE_XATOL_HZ = 1e-4
#: samples either side of a change point that must remain (s)
MIN_SEGMENT_S = 0.25
#: lines at the excitation's first harmonics belong to the motion, not to a separate source
MAX_HARMONIC = 10
#: a table log sees a line when its acceleration is at least this share of the sensor's
SEEN_BY_TABLE = 0.3
#: ... and stands this far above the log's own level at the neighbouring frequencies
TABLE_LINE_SNR = 4.0

ColumnFn = Callable[[StepReplay, np.ndarray], np.ndarray]


@dataclass
class Proposal:
    """One generic extension: its kind, columns and how to describe the fitted result.

    ``columns(step, alpha_dps2)`` returns the step's (n, m) columns; ``describe(coef, K)``
    turns the fitted coefficients into (description, extension parameters).
    """

    kind: str
    key: str
    columns: ColumnFn
    describe: Callable[[np.ndarray, float], tuple[str, dict[str, Any]]]
    #: nonlinear parameters chosen from the data (a frequency, a change point)
    shape_params: int = 0
    info: dict[str, Any] = field(default_factory=dict)


def _alpha_proposals(range_dps2: float) -> list[Proposal]:
    """Even-order and asymmetric static responses to the sensed acceleration α."""

    def even(coef: np.ndarray, k: float) -> tuple[str, dict[str, Any]]:
        c2 = float(coef[0] / k)
        return (f"even-order static non-linearity: output ∝ α², c2 = {c2:.3g} of the range "
                "(the same sign for +α and −α, not a cubic)",
                {"model": "K·(α + c2·α²/α_range)", "c2": c2})

    def asym(coef: np.ndarray, k: float) -> tuple[str, dict[str, Any]]:
        d = float(coef[0] / k)
        return (f"asymmetric scale factor: K+ / K− = {(1 + d) / (1 - d):.5f} "
                f"({200 * d:.3g} % apart)", {"model": "K·α·(1 ± d) for α ≷ 0", "d": d,
                                              "scale_pos_rel": 1 + d, "scale_neg_rel": 1 - d})

    return [Proposal("static_nonlinearity", "alpha^2",
                     lambda sr, a: (a * a / range_dps2)[:, None], even),
            Proposal("asymmetry", "|alpha|", lambda sr, a: np.abs(a)[:, None], asym)]


def _session_times_s(steps: tuple[StepReplay, ...]) -> dict[int, np.ndarray]:
    """Elapsed session time (s) of every sample, steps back to back in recorded order."""
    out, start = {}, 0.0
    for sr in steps:
        out[sr.index] = start + sr.time_s
        start += float(sr.time_s[-1]) + sr.dt_s
    return out


def _trend_proposal(steps: tuple[StepReplay, ...]) -> Proposal:
    elapsed = _session_times_s(steps)

    def columns(sr: StepReplay, a: np.ndarray) -> np.ndarray:
        tau_h = elapsed[sr.index] / 3600.0
        return np.column_stack([tau_h, a * tau_h])

    def describe(coef: np.ndarray, k: float) -> tuple[str, dict[str, Any]]:
        bias, scale = float(coef[0]), float(coef[1] / k)
        return (f"drift with elapsed time: scale factor {100 * scale:+.3g} %/h, bias "
                f"{1e3 * bias:+.3g} mV/h (steps taken back to back)",
                {"model": "b0 + b1·t + K·α·(1 + s1·t), t in hours of recording",
                 "bias_v_per_h": bias, "scale_per_h": scale})

    return Proposal("trend", "trend", columns, describe)


def _change_point(r: np.ndarray, margin: int) -> tuple[int, float]:
    """(index, statistic) of the single mean shift that best splits ``r`` (CUSUM)."""
    n = r.size
    k = np.arange(margin, n - margin)
    c = np.cumsum(r - r.mean())[k - 1]
    stat = np.abs(c) * np.sqrt(n / (k * (n - k)))
    best = int(np.argmax(stat))
    return int(k[best]), float(stat[best] / r.std())


def _step_change_proposal(steps: tuple[StepReplay, ...], residuals: dict[int, np.ndarray]
                          ) -> Proposal | None:
    """The strongest single bias step inside any record, as a generic extension."""
    best: tuple[float, StepReplay, int] | None = None
    for sr in steps:
        margin = int(MIN_SEGMENT_S / sr.dt_s)
        if sr.n <= 4 * margin:
            continue
        idx, stat = _change_point(residuals[sr.index], margin)
        if best is None or stat > best[0]:
            best = (stat, sr, idx)
    if best is None:
        return None
    _, at, idx = best
    t_at = float(at.time_s[idx])

    def columns(sr: StepReplay, a: np.ndarray) -> np.ndarray:
        return ((sr.time_s >= t_at) * (sr.index == at.index)).astype(float)[:, None]

    def describe(coef: np.ndarray, k: float) -> tuple[str, dict[str, Any]]:
        return (f"bias step of {1e3 * float(coef[0]):+.3g} mV at {t_at:.3f} s into step "
                f"{at.step.id}", {"model": "b0 + Δb·[t ≥ t_step] in one record",
                                  "step": at.step.id, "time_s": t_at, "delta_v": float(coef[0])})

    return Proposal("step_change", f"step@{at.step.id}", columns, describe, shape_params=1)


def _linear_detrend(x: np.ndarray) -> np.ndarray:
    """Remove a straight line (what ``detrend="linear"`` does; scipy-stubs mistype that name)."""
    return np.asarray(signal.detrend(x, type="linear"))


def _line_power(steps: tuple[StepReplay, ...], residuals: dict[int, np.ndarray], f_hz: float
                ) -> float:
    """Σ over steps of the power a sine at ``f_hz`` (phase free per step) takes out of the
    residual: the least-squares (Lomb–Scargle) power, not the periodogram, whose peak the
    negative-frequency image pulls off a line with few cycles in the record (by 1.8 mHz for
    13 cycles of 3.3 Hz)."""
    return float(sum(lomb_scargle_at(sr.time_s, residuals[sr.index]
                                     - residuals[sr.index].mean(), f_hz) for sr in steps))


def harmonic_of(f_hz: float, sr: StepReplay, tol_hz: float) -> int | None:
    """The order k when ``f_hz`` is within ``tol_hz`` of k·f0 of the step's excitation
    (k ≤ :data:`MAX_HARMONIC`), else None."""
    f0 = sr.inner.frequency_hz or sr.outer.frequency_hz
    if f0 <= 0:
        return None
    k = round(f_hz / f0)
    return k if 1 <= k <= MAX_HARMONIC and abs(f_hz - k * f0) <= tol_hz else None


def _harmonic_only(f_hz: float, steps: tuple[StepReplay, ...], carriers: list[int],
                   tol_hz: float) -> bool:
    """Whether every step that carries the line has it at a harmonic of its own excitation.

    Such a line is the motion distorted (a static non-linearity, a timing error), which the
    named effects and the α-shaped extensions model; a line that also stands in a step where
    it is no harmonic — a static step, another excitation frequency — has a source of its own,
    whatever frequency it happens to share with some excitation's harmonic.
    """
    return bool(carriers) and all(harmonic_of(f_hz, steps[j], tol_hz) is not None
                                  for j in carriers)


def _peak_frequencies(steps: tuple[StepReplay, ...], residuals: dict[int, np.ndarray]
                      ) -> list[float]:
    """Frequencies (Hz) of residual lines over the whole band, strongest first.

    A line is a peak of the step-averaged spectrum (each step normalised by its own median
    level) or of one step's spectrum alone (a line present only in some steps); its frequency
    is then estimated by maximising the summed periodogram (not snapped to a bin or a nominal
    value). Lines that are only harmonics of the excitation are left to the motion models.
    """
    fs = 1.0 / steps[0].dt_s
    nper = int(min(4096, *(sr.n for sr in steps)))
    spectra = [signal.welch(residuals[sr.index], fs=fs, nperseg=nper, detrend=_linear_detrend)
               for sr in steps]
    f = spectra[0][0]
    norm = np.array([p / max(float(np.median(p)), TINY) for _, p in spectra])
    acc = norm.mean(axis=0)
    floor = float(np.median(acc))
    # one step alone must stand higher: its spectrum is not averaged over the others
    score = np.maximum(acc / (LINE_SNR * floor), norm.max(axis=0) / (2.0 * LINE_SNR))
    peaks, _ = signal.find_peaks(score, height=1.0, distance=4)
    df = fs / nper
    idx = sorted((int(i) for i in peaks if f[i] > 2.0 * df), key=lambda i: -score[i])
    tol_hz = 2.0 / min(sr.n * sr.dt_s for sr in steps)  # two bins of the shortest record
    out: list[float] = []
    for i in idx:
        if len(out) == MAX_LINES:
            break
        res = optimize.minimize_scalar(lambda x: -_line_power(steps, residuals, x),
                                       bounds=(f[i] - df, f[i] + df), method="bounded",
                                       options={"xatol": LINE_XATOL_HZ})
        carriers = [j for j in range(len(steps)) if norm[j, i] >= LINE_SNR]
        if not _harmonic_only(float(res.x), steps, carriers, tol_hz):
            out.append(float(res.x))
    return out


def table_line_dps2(sr: StepReplay, f_hz: float) -> float:
    """Acceleration amplitude (°/s²) of a line at ``f_hz`` in the table's position log; 0 when
    it does not stand :data:`TABLE_LINE_SNR` times above the log's own level around ``f_hz``.

    The position log's noise, differentiated twice, grows as f²: at hundreds of hertz it is
    tens of °/s² in every bin, which is not a line the table moved with.
    """
    amp = 0.0
    df = 1.0 / (sr.n * sr.dt_s)
    around = f_hz + df * np.concatenate([-np.arange(3, 11), np.arange(3, 11)])
    uniform = is_uniform(sr.time_s)  # 17 sums per axis on one grid: checked once
    for dev in sr.table_deviation_deg.values():
        d = dev - dev.mean()
        line = abs(dft_at(d, sr.time_s, f_hz, uniform))
        level = float(np.median([abs(dft_at(d, sr.time_s, g, uniform))
                                 for g in around if g > 0]))
        if line > TABLE_LINE_SNR * level:
            amp = max(amp, 2.0 * line / dev.size * (2 * np.pi * f_hz) ** 2)
    return amp


def _line_proposal(steps: tuple[StepReplay, ...], f_hz: float) -> Proposal:
    index = {sr.index: j for j, sr in enumerate(steps)}
    table_dps2 = max(table_line_dps2(sr, f_hz) for sr in steps)
    tol_hz = 2.0 / min(sr.n * sr.dt_s for sr in steps)
    orders = [harmonic_of(f_hz, sr, tol_hz) for sr in steps]

    def columns(sr: StepReplay, a: np.ndarray) -> np.ndarray:
        w = 2 * np.pi * f_hz * sr.time_s
        out = np.zeros((sr.n, 2 * len(steps)))
        out[:, 2 * index[sr.index]] = np.sin(w)
        out[:, 2 * index[sr.index] + 1] = np.cos(w)
        return out

    def describe(coef: np.ndarray, k: float) -> tuple[str, dict[str, Any]]:
        amps = np.hypot(coef[0::2], coef[1::2])
        phases = np.arctan2(coef[1::2], coef[0::2])
        amp_v = float(np.median(amps))
        # phase coherence over steps (1 = the same phase at every record start)
        coherence = float(abs(np.sum(amps * np.exp(1j * phases))) / max(amps.sum(), TINY))
        seen = table_dps2 >= SEEN_BY_TABLE * amp_v / abs(k)
        where = ("also in the table log (motion)" if seen
                 else "in the sensor only (not in the table log)")
        # steps where the line coincides with a harmonic of that step's own excitation
        strong = amps >= 0.5 * float(amps.max())
        harmonic = [{"step": sr.step.id, "order": o} for sr, o, s in
                    zip(steps, orders, strong, strict=True) if o is not None and s]
        also = (f"; at harmonic {harmonic[0]['order']} of step {harmonic[0]['step']}'s "
                f"excitation too ({len(harmonic)} of {int(strong.sum())} strong steps)"
                if harmonic else "")
        return (f"{f_hz:.3f} Hz line, {1e3 * amp_v:.2g} mV, {where}{also}",
                {"model": "A_i·sin(2π·f·t + φ_i) per step", "frequency_hz": f_hz,
                 "amplitude_v": amp_v, "amplitude_v_per_step": amps.tolist(),
                 "phase_rad_per_step": phases.tolist(), "phase_coherence": coherence,
                 "seen_by_table": bool(seen), "classification": (
                     "also in the table log" if seen else "sensor only"),
                 "harmonic_of_excitation": harmonic,
                 "table_accel_dps2": table_dps2})

    return Proposal("spectral_line", f"line@{f_hz:.2f}", columns, describe, shape_params=1)


def proposals(steps: tuple[StepReplay, ...], residuals: dict[int, np.ndarray],
              range_dps2: float) -> list[Proposal]:
    """Every generic extension the residual suggests (before any is fitted)."""
    out = [*_alpha_proposals(range_dps2), _trend_proposal(steps)]
    change = _step_change_proposal(steps, residuals)
    out += [change] if change is not None else []
    out += [_line_proposal(steps, f) for f in _peak_frequencies(steps, residuals)]
    return out
