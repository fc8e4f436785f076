"""The noise floor a residual is judged against, estimated from the data itself.

"The nominal model explains the data" is a claim about the residual: it must be noise. The
stated datasheet noise is not evidence of that (cabling, a slip ring or a different unit
change it), so the floor is read from the recorded residual itself:

* each step's residual spectrum (Welch, Hann, 50 % overlap) is smoothed by a running
  median *across frequency*, wide enough that narrow lines, the harmonics of the excitation
  and the few lowest bins where slow trends and steps live are outvoted by the broadband
  level around them — what remains is the noise's own spectral shape, logger filter and all;
* that smoothed spectrum, corrected for the median's bias on a χ² variable with the Welch
  estimate's equivalent degrees of freedom, integrates to the noise variance of the step;
* steps pool by their sample counts.

Structure in the residual is what stands above this floor: ``ratio`` = held-out residual RMS
over the floor RMS is 1 for noise, and the pipeline calls the data explained only when it is
at most :data:`EXPLAINED_RATIO`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage, signal, stats

#: held-out residual RMS over the noise floor up to which the residual is called noise
#: (10 % more RMS = 21 % more variance than the broadband noise: a clean record's held-out
#: residual sits within a few % of its floor, the floor's own scatter is ≈ 1 %)
EXPLAINED_RATIO = 1.1
#: Welch segment length (samples), at most; shorter records use a quarter of their length
_NPERSEG = 2048
#: running-median window across frequency, as a share of the bins (odd, at least 9 bins)
_MEDIAN_SHARE = 1.0 / 16.0
METHOD = ("broadband level of each step's residual spectrum (Welch PSD, running median across "
          "frequency so narrow lines, harmonics and slow structure are excluded), integrated "
          "over the band and pooled over the steps")


@dataclass(frozen=True)
class NoiseFloor:
    """The residual's noise floor and how it was read."""

    rms_v: float
    method: str
    #: step id → the step's own floor (V RMS)
    per_step_v: dict[str, float]

    def ratio(self, rms_v: float) -> float:
        """``rms_v`` in units of the floor (inf when the floor is zero)."""
        return rms_v / self.rms_v if self.rms_v > 0 else float("inf")


def _welch_dof(segments: int) -> float:
    """Equivalent χ² degrees of freedom of a Hann, 50 %-overlap Welch average
    (Percival & Walden 1993, eq. 292b)."""
    return 36.0 * segments**2 / (19.0 * segments - 1.0) if segments > 1 else 2.0


def step_floor_variance(residual_v: np.ndarray, dt_s: float) -> float:
    """Noise variance (V²) of one record's residual: its smoothed broadband spectrum."""
    r = np.asarray(residual_v, dtype=np.float64)
    nper = int(min(_NPERSEG, max(64, r.size // 4)))
    f, p = signal.welch(r, fs=1.0 / dt_s, nperseg=nper,
                        detrend=lambda x: np.asarray(signal.detrend(x, type="linear")))
    p = p[1:]  # the DC bin holds the mean and the slowest trend, not noise
    window = min(p.size, max(9, int(p.size * _MEDIAN_SHARE) | 1))
    smooth = ndimage.median_filter(p, size=window, mode="nearest")
    # at the band edges the window slides inside instead of padding: padding would repeat the
    # lowest bins, where slow structure lives, until they outvote the noise around them
    half = window // 2
    smooth[:half] = np.median(p[:window])
    smooth[p.size - half:] = np.median(p[p.size - window:])
    segments = max(1, 1 + (r.size - nper) // (nper // 2))
    dof = _welch_dof(segments)
    bias = float(stats.chi2.median(dof) / dof)  # median / mean of a χ²_ν / ν variable
    return float(np.sum(smooth) * (f[1] - f[0]) / bias)


def noise_floor(residuals: dict[str, np.ndarray], dt_s: float) -> NoiseFloor:
    """The pooled noise floor of per-step residuals (step id → residual, V)."""
    variances = {sid: step_floor_variance(r, dt_s) for sid, r in residuals.items()}
    counts = {sid: r.size for sid, r in residuals.items()}
    total = sum(counts.values())
    pooled = sum(variances[s] * counts[s] for s in variances) / max(total, 1)
    return NoiseFloor(float(np.sqrt(pooled)), METHOD,
                      {s: float(np.sqrt(v)) for s, v in variances.items()})
