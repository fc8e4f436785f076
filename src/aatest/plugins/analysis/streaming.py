"""Reductions of a record fed block by block: moments, Welch PSD and Allan-deviation input.

Why: a long static record (hours at 2 kHz, 10⁸ samples) is read from the recording piece by
piece (:meth:`aatest.clocksync.freeze_pulse.SyncedStep.daq_blocks`); the static analyses (bias,
noise, temperature) reduce each block as it comes — vectorised within the block — and keep
only the reductions, so their memory does not grow with the record. On a record held in memory
(one block) every reduction gives what the whole-array computation gives, to rounding.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import signal

from aatest.plugins.analysis.drift import BlockMeans

#: most averaged values an Allan deviation is computed from (2 MB of float64; allantools
#: holds several arrays of this length while it computes)
MAX_ALLAN_POINTS = 2**18
#: Welch segment length, samples (the record's, when shorter)
WELCH_SEGMENT = 2**13


@dataclass
class Moments:
    """Count, mean and sum of squared deviations of values fed in blocks (Chan et al.'s
    pairwise update: exact to rounding, no cancellation however long the record)."""

    n: int = 0
    mean: float = 0.0
    m2: float = 0.0

    def add(self, values: np.ndarray) -> None:
        """Feed the next values."""
        x = np.asarray(values, dtype=np.float64)
        m = int(x.size)
        if m == 0:
            return
        mean_b = float(x.mean())
        d = x - mean_b
        m2_b = float(d @ d)
        n = self.n + m
        delta = mean_b - self.mean
        self.m2 += m2_b + delta * delta * self.n * m / n
        self.mean += delta * m / n
        self.n = n

    @property
    def std(self) -> float:
        """Population standard deviation (as ``np.std``)."""
        return float(np.sqrt(self.m2 / self.n)) if self.n else float("nan")


@dataclass
class StreamedWelch:
    """Welch's PSD (Hann window, half overlap, constant detrend, density) of a record of
    known length fed in blocks: the segments lie on the whole record's grid, so the average
    is ``scipy.signal.welch`` of the whole record."""

    fs_hz: float
    samples: int
    _carry: np.ndarray = field(default_factory=lambda: np.empty(0))
    _sum: np.ndarray | None = None
    _segments: int = 0
    _f: np.ndarray | None = None

    @property
    def nperseg(self) -> int:
        """Segment length, samples."""
        return int(min(self.samples, WELCH_SEGMENT))

    def add(self, values: np.ndarray) -> None:
        """Feed the next samples of the record."""
        data = np.concatenate([self._carry, np.asarray(values, dtype=np.float64)])
        nper, step = self.nperseg, self.nperseg - self.nperseg // 2
        if data.size < nper:
            self._carry = data
            return
        count = (data.size - nper) // step + 1
        used = (count - 1) * step + nper
        f, psd = signal.welch(data[:used], fs=self.fs_hz, nperseg=nper, detrend="constant")
        self._f = f
        self._sum = psd * count if self._sum is None else self._sum + psd * count
        self._segments += count
        self._carry = data[count * step:].copy()

    def result(self) -> tuple[np.ndarray, np.ndarray]:
        """(frequency Hz, PSD in the input's unit²/Hz) of every complete segment."""
        if self._sum is None or self._f is None:
            raise ValueError("a record shorter than one Welch segment has no PSD")
        return self._f, self._sum / self._segments


def band_rms_of(f: np.ndarray, psd: np.ndarray, band_hz: float) -> float:
    """RMS (input unit) between DC and ``band_hz`` from a one-sided PSD."""
    inband = f <= band_hz
    return float(np.sqrt(np.trapezoid(psd[inband], f[inband])))


def allan_block(samples: int) -> int:
    """Samples per mean the Allan deviation of a ``samples``-long record is computed from:
    1 (the samples themselves) up to :data:`MAX_ALLAN_POINTS`, else the fewest that keep the
    means within it (the deviation then starts at that τ; overlap is by whole means)."""
    return max(1, -(-samples // MAX_ALLAN_POINTS))


@dataclass
class StaticReduction:
    """What the static analyses keep of one record and channel: its moments, Welch PSD and
    (when asked) its block means for the Allan deviation."""

    moments: Moments
    welch: StreamedWelch | None
    allan: BlockMeans | None


def reduce_static(blocks: Iterable[Mapping[str, np.ndarray]], channels: Sequence[str],
                  fs_hz: float, samples: int, spectra: bool = False,
                  allan: bool = False) -> dict[str, StaticReduction]:
    """One pass over a record's blocks: per channel its moments, and optionally its Welch
    PSD (``spectra``) and Allan-deviation means (``allan``; :func:`allan_block` samples each).
    A channel the record lacks is left out."""
    per = allan_block(samples)
    out: dict[str, StaticReduction] = {}
    for block in blocks:
        for ch in channels:
            if ch not in block:
                continue
            if ch not in out:
                out[ch] = StaticReduction(
                    Moments(), StreamedWelch(fs_hz, samples) if spectra else None,
                    BlockMeans(per) if allan else None)
            red = out[ch]
            red.moments.add(block[ch])
            if red.welch is not None:
                red.welch.add(block[ch])
            if red.allan is not None:
                red.allan.add(block[ch])
    return out
