"""Angular-acceleration references built from the table's logs (docs/method.md §1.2, §4.3).

A position table measures position and rate superbly but acceleration badly: its own estimate
is a double difference of the position estimate, dominated by high-frequency noise. The
references offered here:

``table``               the controller's logged acceleration estimate;
``central_position``    central second difference of the position estimate;
``five_point_position`` five-point second difference of the position estimate;
``central_rate``        central first difference of the rate estimate;
``five_point_rate``     five-point first difference of the rate estimate;
``savgol``              zero-phase Savitzky–Golay smoothing differentiator (2nd derivative of
                        position);
``smooth``              smoothed differentiation: central second difference of the position
                        estimate through a zero-phase Butterworth low-pass (``sosfiltfilt``) at
                        its own stated corner, :data:`SMOOTHED_CORNER_HZ` (not the corner the
                        sensor volts are filtered at);
``levant``              Levant's first-order sliding-mode differentiator of the rate estimate.

Levant's differentiator is recursive and cannot be vectorised; it runs as a scalar loop over
Python floats (measured 0.024 s per 2^17-sample record on this machine; see
:func:`levant_differentiator`), which is acceptable next to the minutes a record takes.
"""

from __future__ import annotations

import math
import time
from typing import ClassVar

import numpy as np
from pydantic import BaseModel, ConfigDict, Field
from scipy import signal

from aatest.clocksync.freeze_pulse import SyncedStep
from aatest.engine.interfaces import AnalysisContext, AnalysisOutput
from aatest.engine.requirements import Requirement
from aatest.plugins.analysis import needs
from aatest.plugins.analysis._common import fundamental, options_of, steps_of
from aatest.recording.dataset import Dataset
from aatest.results.reference import ReferenceResult
from aatest.results.scale_factor import ReferenceChoice

METHODS = ("table", "central_position", "five_point_position", "central_rate",
           "five_point_rate", "savgol", "smooth", "levant")
#: the public reference names (procedure options, results) → the method implementing each:
#: ``central``/``five_point`` differentiate the rate estimate once (the position estimate
#: twice would amplify its noise by far more)
PUBLIC_METHODS: dict[ReferenceChoice, str] = {
    "fit": "savgol", "table_estimate": "table", "central": "central_rate",
    "five_point": "five_point_rate", "smoothed": "smooth", "sliding_mode": "levant"}


#: corner of the ``smooth`` reference's zero-phase low-pass (4th order, run forwards and
#: backwards): above the 10 Hz top of the stepped-sine grid (|H|² = 0.9993 there), below the
#: 30–40 Hz motor band and the 60–130 Hz rate ripple the table estimate carries
SMOOTHED_CORNER_HZ = 25.0

#: samples the central first difference needs
_STENCIL = 2


def _pad_edges(x: np.ndarray, width: int) -> np.ndarray:
    """Repeat the first/last valid stencil value into the ``width`` edge samples."""
    out = np.asarray(x, dtype=np.float64)
    out[:width] = out[width]
    out[-width:] = out[-width - 1]
    return out


def second_difference(position_deg: np.ndarray, fs_hz: float, stencil: str = "central"
                      ) -> np.ndarray:
    """Second derivative of a position, °/s², by the central or five-point stencil."""
    f = np.asarray(position_deg, dtype=np.float64)
    out = np.zeros_like(f)
    if stencil == "central":
        out[1:-1] = (f[2:] - 2 * f[1:-1] + f[:-2]) * fs_hz**2
        return _pad_edges(out, 1)
    out[2:-2] = (-f[4:] + 16 * f[3:-1] - 30 * f[2:-2] + 16 * f[1:-3] - f[:-4]) * fs_hz**2 / 12
    return _pad_edges(out, 2)


def first_difference(x: np.ndarray, fs_hz: float, stencil: str = "central") -> np.ndarray:
    """First derivative by the central or five-point stencil (units of x per second)."""
    f = np.asarray(x, dtype=np.float64)
    out = np.zeros_like(f)
    if stencil == "central":
        out[1:-1] = (f[2:] - f[:-2]) * fs_hz / 2
        return _pad_edges(out, 1)
    out[2:-2] = (-f[4:] + 8 * f[3:-1] - 8 * f[1:-3] + f[:-4]) * fs_hz / 12
    return _pad_edges(out, 2)


def savgol_accel(position_deg: np.ndarray, fs_hz: float, window_s: float = 0.025,
                 polyorder: int = 5) -> np.ndarray:
    """Zero-phase smoothing second derivative (Savitzky–Golay), °/s².

    The symmetric window has no phase lag; 25 ms with a quintic passes a 10 Hz sine with
    0.05 % loss (a cubic would lose 4.5 %). The window holds at least ``polyorder + 2``
    samples (odd), the fewest a fit of that order can smooth: a log slower than 260 Hz gets a
    window longer than ``window_s``.
    """
    window = max(round(window_s * fs_hz), polyorder + 1) | 1
    return signal.savgol_filter(np.asarray(position_deg, dtype=np.float64), window, polyorder,
                                deriv=2, delta=1.0 / fs_hz, mode="interp")


def zero_phase_lowpass(x: np.ndarray, fs_hz: float, cutoff_hz: float, order: int = 4
                       ) -> np.ndarray:
    """Butterworth low-pass run forwards and backwards: no phase lag, squared magnitude."""
    sos = signal.butter(order, cutoff_hz, fs=fs_hz, output="sos")
    return signal.sosfiltfilt(sos, np.asarray(x, dtype=np.float64))


def smoothed_accel(position_deg: np.ndarray, fs_hz: float,
                   corner_hz: float = SMOOTHED_CORNER_HZ) -> np.ndarray:
    """Smoothed differentiation of the position estimate, °/s²: central second difference
    through a zero-phase 4th-order Butterworth low-pass at ``corner_hz``.

    Linear and zero-phase: its response is (2cos ωh − 2)/h² · |H_bw(f)|², so on white position
    noise σ its noise is σ/h²·√(mean over f of that squared) (tests check that amount).
    """
    return zero_phase_lowpass(second_difference(position_deg, fs_hz, "central"), fs_hz,
                              corner_hz)


def levant_differentiator(rate_dps: np.ndarray, fs_hz: float, lipschitz_dps3: float
                          ) -> np.ndarray:
    """Levant's first-order sliding-mode differentiator of a rate, °/s² (docs/method.md §4.3).

    y′ = α, α = v − λ·|y − ω|^½·sign(y − ω), v′ = −β·sign(y − ω), with β = 2C and
    λ = √(4C(β + C)/(β − C)) = √(12·C), C the Lipschitz bound of dα/dt (jerk, °/s³).
    Explicit Euler at the sample period. Recursive by nature, hence a scalar loop on Python
    floats (no NumPy scalars); measured ≈0.2 µs per sample (0.024 s per 2^17 samples).
    """
    c = float(lipschitz_dps3)
    beta = 2.0 * c
    lam = math.sqrt(4.0 * c * (beta + c) / (beta - c))
    h = 1.0 / fs_hz
    omega = np.asarray(rate_dps, dtype=np.float64).tolist()
    out = [0.0] * len(omega)
    y, v = omega[0], (omega[1] - omega[0]) * fs_hz if len(omega) > 1 else 0.0
    sqrt, copysign = math.sqrt, math.copysign
    for k, w in enumerate(omega):
        e = y - w
        s = copysign(1.0, e) if e != 0.0 else 0.0
        a = v - lam * sqrt(abs(e)) * s
        out[k] = a
        y += h * a
        v -= h * beta * s
    return np.asarray(out)


def reference_accel(synced: SyncedStep, method: str = "smooth", cutoff_hz: float | None = None
                    ) -> np.ndarray:
    """Acceleration of the step's moving axis, °/s², by one of :data:`METHODS`."""
    axis = synced.step.axis if synced.step.axis in ("inner", "outer") else "inner"
    pos, rate = synced.table[f"{axis}_position_deg"], synced.table[f"{axis}_rate_dps"]
    est, fs = synced.table[f"{axis}_accel_dps2"], synced.sample_rate_hz
    if method == "table":
        return np.asarray(est, dtype=np.float64)
    if method in ("central_position", "five_point_position"):
        return second_difference(pos, fs, method.split("_p", maxsplit=1)[0])
    if method in ("central_rate", "five_point_rate"):
        return first_difference(rate, fs, method.split("_r", maxsplit=1)[0])
    if method == "savgol":
        return savgol_accel(pos, fs)
    if method == "smooth":
        return smoothed_accel(pos, fs, cutoff_hz or SMOOTHED_CORNER_HZ)
    if method == "levant":
        smooth = zero_phase_lowpass(est, fs, default_cutoff_hz(synced))
        jerk = np.max(np.abs(first_difference(smooth, fs))) if smooth.size > _STENCIL else 1.0
        # the smoothed estimate's peak jerk already bounds the true one from above (its noise
        # adds), and β = 2C is the margin Levant's condition β > C asks for: a further factor
        # only raises the chattering (×2 doubles the RMS error on the study's 1 Hz record)
        return levant_differentiator(rate, fs, max(jerk, 1.0))
    raise ValueError(f"unknown reference {method!r}; choose one of {', '.join(METHODS)}")


def default_cutoff_hz(synced: SyncedStep) -> float:
    """Low-pass corner of the sensor volts (and of the ``levant`` reference's jerk bound):
    well above the excitation and its low harmonics (8·f, at least 20 Hz), well below
    Nyquist."""
    f0 = synced.step.frequency_hz or 1.0
    return float(min(max(20.0, 8.0 * f0), 0.2 * synced.sample_rate_hz))


def _compare(synced: SyncedStep) -> dict[str, dict[str, float]]:
    """Each reference against the smooth one: fundamental gain/phase and RMS difference."""
    fs, f0 = synced.sample_rate_hz, float(synced.step.frequency_hz or 0.0)
    base = reference_accel(synced, "smooth")
    edge = int(0.05 * len(synced))
    out: dict[str, dict[str, float]] = {}
    for method in METHODS:
        t0 = time.perf_counter()
        ref = reference_accel(synced, method)
        elapsed = time.perf_counter() - t0
        row = {"rms_diff_dps2": float(np.sqrt(np.mean((ref - base)[edge:-edge] ** 2))),
               "runtime_s": elapsed}
        if f0 > 0:
            ratio = fundamental(ref, f0, fs) / fundamental(base, f0, fs)
            row |= {"gain": abs(ratio), "phase_deg": float(np.degrees(np.angle(ratio)))}
        out[method] = row
    return out


class ReferenceOptions(BaseModel):
    """How many sine steps to compare the references on (each comparison runs all eight)."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    max_steps: int = Field(3, ge=1, description="sine steps compared, in plan order")


class ReferenceAnalysis:
    """Compares the acceleration references on every sine step (which one to trust)."""

    key: ClassVar[str] = "reference"
    requires: ClassVar[tuple[str, ...]] = ("sync",)
    #: what the plan must hold (checked by ``validate``; aatest.engine.requirements)
    requirements: ClassVar[tuple[Requirement, ...]] = needs.SINE
    #: the acceptance quantities it produces (judged when it is listed)
    judges: ClassVar[tuple[str, ...]] = ()
    Options: ClassVar[type[ReferenceOptions]] = ReferenceOptions
    Result: ClassVar[type[ReferenceResult]] = ReferenceResult

    def applies_to(self, data: Dataset) -> bool:
        return any(s.step.kind == "sine" for s in data.steps)

    def run(self, data: Dataset, context: AnalysisContext) -> AnalysisOutput[ReferenceResult]:
        options = options_of(context, ReferenceOptions)
        steps = steps_of(context, "sine")[:options.max_steps]
        rows = {s.step.id: _compare(s) for s in steps}
        return AnalysisOutput(ReferenceResult.model_validate(rows))
