"""Bias drift and the Allan deviation to τ ≥ 1000 s of a long static record (docs/method.md §1.3).

The ``drift`` analysis (:class:`DriftAnalysis`) reads a long static record (hours, streamed by
the DAQ): the 2 kHz output averaged to 1 s, its bias drift (slope V/h, peak-to-peak, bias and
temperature per 30 min) and the overlapping Allan deviation to τ ≥ 1000 s with white noise N,
bias instability B, rate random walk K and rate ramp R fitted.

Bounded memory: a recorded step is read piece by piece (its blocks) and reduced on the way to
its 20 Hz block means and its 1 s means of time and temperature; only those (1/100 of the
record and less) are kept, so a record of any length costs about the same memory. The
reductions are the ones the whole record would get, to the bit (:class:`BlockMeans`).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from aatest.engine.errors import AnalysisError
from aatest.engine.interfaces import AnalysisContext, AnalysisOutput
from aatest.engine.logs import SampledLog
from aatest.engine.requirements import Requirement
from aatest.plugins.analysis import needs
from aatest.plugins.analysis._common import options_of
from aatest.presentation.figures import new_figure, tight_layout, to_svg
from aatest.recording.dataset import Dataset, LazySteps
from aatest.results.noise import DriftResult

_SLOPE_TOL = 0.15
#: points needed to read local log-log slopes off an Allan curve
_MIN_SLOPE_POINTS = 3


#: the bias peak-to-peak is taken over means of this length, s (white noise averaged out)
_PEAK_TO_PEAK_WINDOW_S = 60.0
#: first reduction stage of a long record, s (block means at 20 Hz)
_STAGE_S = 0.05
#: an Allan-fit term below this share of the variance at every τ is reported as absent
_MIN_TERM_SHARE = 1e-3
#: a 0/1 logic channel is high above this level
_LOGIC_HIGH = 0.5
#: fewest averaged values a drift fit and an Allan curve are made from
_MIN_MEANS = 4
#: minimum clusters at the longest τ of a reported Allan deviation (oadev: τ ≤ T/2)
_MIN_CLUSTERS = 2


#: samples reduced per pass of :func:`block_means` (8 MB of float64: a bounded temporary)
_BLOCK_MEANS_CHUNK = 2**20


def block_means(values: np.ndarray, per_block: int, origin: float = 0.0) -> np.ndarray:
    """Means of consecutive non-overlapping blocks of ``per_block`` samples (any unit) of
    ``values − origin``; the incomplete tail is dropped.

    Vectorised over rows of a reshaped view, a bounded number of rows at a time: an hours-long
    record (or its time stamps less their first, ``origin``) is never copied whole. Each row's
    mean is computed exactly as on the whole array, so the result does not depend on the chunk.
    """
    whole = values.size // per_block
    out = np.empty(whole, dtype=float)
    rows = max(1, _BLOCK_MEANS_CHUNK // per_block)
    for first in range(0, whole, rows):
        last = min(whole, first + rows)
        part = np.asarray(values[first * per_block: last * per_block], dtype=float)
        if origin:
            part = part - origin
        out[first:last] = part.reshape(last - first, per_block).mean(1)
    return out


class BlockMeans:
    """:func:`block_means` of a record fed piece by piece (any unit; ``origin`` subtracted).

    The samples that do not fill a block yet are carried to the next piece, so every block
    is averaged from the same contiguous samples, in the same way, as on the whole record:
    the means are bit-identical whatever the pieces.
    """

    def __init__(self, per_block: int, origin: float = 0.0) -> None:
        self.per_block, self.origin = per_block, origin
        self.samples = 0
        self._carry = np.empty(0)
        self._means: list[np.ndarray] = []

    def add(self, values: np.ndarray) -> None:
        """Feed the next samples of the record."""
        self.samples += int(np.size(values))
        data = np.asarray(values, dtype=float)
        if self._carry.size:
            data = np.concatenate([self._carry, data])
        whole = data.size // self.per_block * self.per_block
        if whole:
            self._means.append(block_means(data[:whole], self.per_block, self.origin))
        self._carry = data[whole:].copy()

    def means(self) -> np.ndarray:
        """The means of every complete block fed so far (the incomplete tail dropped)."""
        return np.concatenate(self._means) if self._means else np.empty(0)


def decimate_means(coarse: np.ndarray, stage: int, fs_hz: float, average_s: float
                   ) -> np.ndarray:
    """Second stage of :func:`reduce_rate`: ``stage``-sample means (of a ``fs_hz`` Hz record)
    low-passed and decimated to one value per ``average_s`` s."""
    from scipy.signal import resample_poly

    factor = max(1, round(average_s * fs_hz / stage))
    if factor == 1:
        return coarse
    whole = coarse.size // factor * factor
    # the edges are padded along a fitted line, so a drifting record has no edge transient
    reduced = resample_poly(coarse[:whole], 1, factor, padtype="line")
    return np.asarray(reduced, dtype=float)


def _stage_samples(fs_hz: float, average_s: float) -> int:
    """Samples per first-stage mean (:data:`_STAGE_S`, or ``average_s`` if shorter)."""
    return max(1, round(min(_STAGE_S, average_s) * fs_hz))


def reduce_rate(values: np.ndarray, fs_hz: float, average_s: float) -> np.ndarray:
    """The record reduced to one value per ``average_s`` s without aliasing (``fs_hz`` in Hz).

    A plain 1 s mean lets a narrow band near a rig line through its sinc sidelobes (the motor's
    35 Hz band: ≈1 % of several °/s², as large as the sensor's own white noise per second). So:
    means over :data:`_STAGE_S` (nulls at multiples of 20 Hz, what is left folds below 10 Hz),
    then a zero-phase FIR low-pass and decimation to ``average_s`` (scipy ``resample_poly``,
    its Kaiser-window filter), which removes the
    folded band and keeps the white-noise density below the new Nyquist frequency. Values in
    the input's unit; the incomplete tail is dropped.
    """
    stage = _stage_samples(fs_hz, average_s)
    return decimate_means(block_means(values, stage), stage, fs_hz, average_s)


@dataclass
class ReducedRecord:
    """A static record after the first reduction: what the drift figures are computed from.

    ``coarse_v`` per channel: means of ``stage`` samples (V); ``time_h``: the means over ``per``
    samples (``average_s``) of the time since the record's first sample (h);
    ``temperature_c``: the same means of the logged temperature (°C), None when not logged;
    ``samples``: the record's length (samples) at ``fs_hz`` (Hz).
    """

    fs_hz: float
    stage: int
    per: int
    samples: int = 0
    coarse_v: dict[str, np.ndarray] = field(default_factory=dict)
    time_h: np.ndarray = field(default_factory=lambda: np.empty(0))
    temperature_c: np.ndarray | None = None


def reduce_record(pieces: Iterable[SampledLog], channels: list[str], start: int,
                  average_s: float) -> ReducedRecord:
    """Reduce a DAQ record, given as consecutive pieces, from sample ``start`` on (the trigger).

    Each piece is dropped once fed to the :class:`BlockMeans` of every ``channels`` entry, of
    the time stamps and of ``temperature_c``; the result equals the whole record's
    (:func:`reduce_rate`'s first stage, the ``average_s`` means of time and temperature) bit
    for bit.
    """
    position, fs_hz = 0, 0.0
    coarse: dict[str, BlockMeans] = {}
    time: BlockMeans | None = None
    temperature: BlockMeans | None = None
    for piece in pieces:
        skip, position = max(0, start - position), position + len(piece)
        if skip >= len(piece):
            continue
        if time is None:
            fs_hz = float(piece.sample_rate_hz)
            stage, per = _stage_samples(fs_hz, average_s), max(1, round(average_s * fs_hz))
            coarse = {ch: BlockMeans(stage) for ch in channels}
            time = BlockMeans(per, origin=float(piece.time_s[skip]))
            if "temperature_c" in piece.channels:
                temperature = BlockMeans(per)
        time.add(piece.time_s[skip:])
        for ch, means in coarse.items():
            means.add(piece[ch][skip:])
        if temperature is not None:
            temperature.add(piece["temperature_c"][skip:])
    if time is None:
        raise AnalysisError("the static record holds no sample after its trigger")
    return ReducedRecord(fs_hz, _stage_samples(fs_hz, average_s), time.per_block, time.samples,
                         {ch: means.means() for ch, means in coarse.items()},
                         time.means() / 3600.0,
                         temperature.means() if temperature is not None else None)


def fit_allan(taus_s: np.ndarray, adev: np.ndarray) -> dict[str, float | None]:
    """N, B, K, R of σ²(τ) = N²/τ + (0.664·B)² + K²·τ/3 + R²·τ²/2 by non-negative least squares
    on the Allan variance, each point weighted by 1/σ² (relative errors count alike).

    ``taus_s`` in s, ``adev`` in the rate-like unit u (°/s²): N in u·√s, B in u, K in u/√s,
    R (rate ramp: a steady drift) in u/s; a term the data do not support comes back None.
    """
    from scipy.optimize import nnls

    taus, var = np.asarray(taus_s, float), np.asarray(adev, float) ** 2
    names = ("white_noise_dps2_sqrt_s", "bias_instability_dps2",
             "rate_random_walk_dps2_per_sqrt_s", "rate_ramp_dps2_per_s")
    if taus.size < len(names):
        return dict.fromkeys(names)
    design = np.column_stack([1.0 / taus, np.ones_like(taus), taus / 3.0, taus**2 / 2.0])
    coef, _ = nnls(design / var[:, None], np.ones_like(taus))
    roots = np.sqrt(coef) * np.array([1.0, 1.0 / 0.664, 1.0, 1.0])
    # a term is supported when it makes at least 0.1 % of the variance somewhere on the curve
    share = (design * coef / var[:, None]).max(axis=0)
    return {name: float(root) if part > _MIN_TERM_SHARE else None
            for name, root, part in zip(names, roots, share, strict=True)}


def drift_of_reduced(reduced: ReducedRecord, channel: str, scale_v_per_dps2: float,
                     average_s: float, interval_s: float) -> dict[str, Any]:
    """Bias drift, interval table and Allan deviation of one channel of a reduced record.

    The record is taken to one value per ``average_s`` s (:func:`decimate_means`), then:
    least-squares line of the bias (V/h), peak-to-peak of its 60 s means (V), mean bias and
    temperature (°C) per ``interval_s`` s, and the overlapping Allan deviation (allantools,
    octave τ) of the means in °/s² (divided by ``scale_v_per_dps2``, V per °/s²) with its
    fitted noise terms. ``_intercept_v``, ``_means_v`` and ``_time_h`` are for the figure.
    """
    import allantools

    per, fs_hz = reduced.per, reduced.fs_hz
    tau0_s = per / fs_hz
    means_v = decimate_means(reduced.coarse_v[channel], reduced.stage, fs_hz, average_s)
    t_h = reduced.time_h[: means_v.size]
    if means_v.size < _MIN_MEANS:
        raise AnalysisError(f"record of {reduced.samples} samples is too short for a drift "
                            f"fit at {average_s} s averaging")
    (slope, intercept), cov = np.polyfit(t_h, means_v, 1, cov=True)
    window = max(1, round(_PEAK_TO_PEAK_WINDOW_S / tau0_s))
    smooth = block_means(means_v, window) if means_v.size >= 2 * window else means_v
    rate = (means_v - means_v.mean()) / scale_v_per_dps2
    taus, adev = allantools.oadev(rate, rate=1.0 / tau0_s, data_type="freq", taus="octave")[:2]
    taus, adev = np.asarray(taus, float), np.asarray(adev, float)
    keep = taus * _MIN_CLUSTERS <= rate.size * tau0_s
    taus, adev = taus[keep], adev[keep]
    per_interval = max(1, round(interval_s / tau0_s))
    starts = np.arange(0, means_v.size, per_interval)
    temps = (reduced.temperature_c[: means_v.size] if reduced.temperature_c is not None
             else None)
    intervals = [{"start_h": float(t_h[i]), "bias_v": float(means_v[i:i + per_interval].mean()),
                  "temperature_c": float(temps[i:i + per_interval].mean())
                  if temps is not None else None} for i in starts]
    return {
        "duration_s": float(reduced.samples / fs_hz), "average_s": tau0_s,
        "bias_v": float(means_v.mean()), "drift_v_per_h": float(slope),
        "drift_sigma_v_per_h": float(np.sqrt(cov[0, 0])),
        "drift_dps2_per_h": float(slope) / scale_v_per_dps2,
        "peak_to_peak_v": float(np.ptp(smooth)), "scale_v_per_dps2_used": scale_v_per_dps2,
        "allan_dps2": allan_terms_of(taus, adev), "allan_fit": fit_allan(taus, adev),
        "max_tau_s": float(taus.max()) if taus.size else 0.0, "intervals": intervals,
        "_intercept_v": float(intercept), "_means_v": means_v, "_time_h": t_h,
    }


def allan_terms_of(taus: np.ndarray, adev: np.ndarray) -> dict[str, Any]:
    """:func:`allan_terms` read off an already computed Allan deviation (τ in s)."""
    slope = (np.gradient(np.log(adev), np.log(taus)) if taus.size >= _MIN_SLOPE_POINTS
             else np.zeros_like(taus))
    white = np.abs(slope + 0.5) < _SLOPE_TOL
    walk = np.abs(slope - 0.5) < _SLOPE_TOL
    return {
        "tau_s": taus.tolist(), "adev": adev.tolist(),
        "white_noise_per_sqrt_hz": float(np.median(adev[white] * np.sqrt(taus[white])))
        if white.any() else None,
        "bias_instability": float(adev.min() / 0.664) if adev.size else None,
        "random_walk": float(np.median(adev[walk] / np.sqrt(taus[walk] / 3.0)))
        if walk.any() else None,
    }


def drift_figure(channel: str, values: dict[str, Any], t_h: np.ndarray,
                 means_v: np.ndarray) -> str:
    """Bias against time with its fitted line, and the Allan deviation (SVG)."""
    fig, ax = new_figure(2, height_in=2.4)
    ax[0, 0].plot(t_h, means_v, lw=0.5, rasterized=True)
    ax[0, 0].plot(t_h, values["_intercept_v"] + values["drift_v_per_h"] * t_h, "k--", lw=0.8)
    ax[0, 0].set(xlabel="time / h", ylabel="bias / V", title=f"bias drift {channel}")
    allan = values["allan_dps2"]
    ax[1, 0].loglog(allan["tau_s"], allan["adev"], "o-", ms=3)
    ax[1, 0].set(xlabel="τ / s", ylabel="Allan dev. / (°/s²)")
    tight_layout(fig)
    return to_svg(fig)


class DriftOptions(BaseModel):
    """How the long record is reduced and reported."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    average_s: float = Field(1.0, gt=0, description="averaging interval before the Allan "
                             "deviation and the drift fit, s")
    temperature_every_s: float = Field(1800.0, gt=0, description="bias and temperature are "
                                       "reported per interval of this length, s")


class DriftAnalysis:
    """Bias drift and Allan deviation (to τ ≥ 1000 s on a 2 h record) of every sensor, from
    the longest static record, read straight from the DAQ log.

    Needs no synchronisation (a long record's table log holds snapshots only) and uses the
    datasheet scale factor for the °/s² figures (a drift test calibrates no scale factor).
    """

    key: ClassVar[str] = "drift"
    requires: ClassVar[tuple[str, ...]] = ()
    #: what the plan must hold (checked by ``validate``; aatest.engine.requirements)
    requirements: ClassVar[tuple[Requirement, ...]] = needs.STATIC
    #: the acceptance quantities it produces (judged when it is listed)
    judges: ClassVar[tuple[str, ...]] = ()
    Options: ClassVar[type[DriftOptions]] = DriftOptions
    Result: ClassVar[type[DriftResult]] = DriftResult

    def applies_to(self, data: Dataset) -> bool:
        return any(s.step.kind == "static" for s in data.steps)

    def run(self, data: Dataset, context: AnalysisContext) -> AnalysisOutput[DriftResult]:
        options = options_of(context, DriftOptions)
        index = longest_static_index(data)
        channels = [sensor.channel for sensor in data.sensors]
        reduced = reduce_record(_record_pieces(data, index, channels), channels,
                                _trigger_sample(data, index), options.average_s)
        values: dict[str, Any] = {}
        figures: dict[str, str] = {}
        for sensor in data.sensors:
            found = drift_of_reduced(reduced, sensor.channel,
                                     float(sensor.nominal_scale_v_per_dps2),
                                     options.average_s, options.temperature_every_s)
            t_h, means_v = found.pop("_time_h"), found.pop("_means_v")
            figures[f"drift_{sensor.channel}"] = drift_figure(sensor.channel, found, t_h, means_v)
            found.pop("_intercept_v")
            values[sensor.channel] = {**found, "record_step": data.planned[index].id}
        return AnalysisOutput(DriftResult.model_validate(values), figures)


def longest_static_index(data: Dataset) -> int:
    """Index of the longest static step, by the sample count its record gives (nothing is
    decoded); the first of equally long ones."""
    static = [i for i, step in enumerate(data.planned) if step.kind == "static"]
    if not static:
        raise AnalysisError("no static step to read a drift record from")
    return max(static, key=lambda i: data.steps[i].samples("daq"))


def _record_pieces(data: Dataset, index: int, channels: list[str]) -> Iterable[SampledLog]:
    """The DAQ log of step ``index``: its sensor channels and ``temperature_c`` piece by piece
    from a recording, the whole log of an in-memory dataset."""
    if isinstance(data.steps, LazySteps):
        return data.steps.pieces(index, "daq", [*channels, "temperature_c"])
    return [data.steps[index].daq]


def _trigger_sample(data: Dataset, index: int) -> int:
    """First DAQ sample of the record proper (trigger high; the logger's lead is before it),
    0 without a trigger channel or a high. A recording's trigger is read piece by piece, and
    only until it goes high."""
    pieces: Iterable[SampledLog] = (data.steps.pieces(index, "daq", ["trigger"])
                                    if isinstance(data.steps, LazySteps)
                                    else [data.steps[index].daq])
    position = 0
    for piece in pieces:
        trigger = piece.channels.get("trigger")
        if trigger is None:
            return 0
        on = np.flatnonzero(np.asarray(trigger) > _LOGIC_HIGH)
        if on.size:
            return position + int(on[0])
        position += len(piece)
    return 0
