"""Candidate discrete transfer functions of one group's FRF, and the one chosen (docs/method.md
§4.4).

Every structure with n = 0..``max_poles`` poles and m ≤ n zeros is fitted without a separate
delay and with the input–output cross-correlation delay (when accepted), and the structures
with n ≤ 2 with every integer delay up to it too (scanned, MATLAB's ``delayest`` idea); each
is identified on the identification points and judged on the validation points
(:func:`split_points`). The chosen model is the best validation fit among stable,
minimum-phase models (within 0.5 % the simplest). Its continuous-time equivalent
(pole/zero matching) gives the natural frequency and damping. The plugin around it
(:mod:`~aatest.plugins.analysis.transfer_function`) groups the FRF points and adds the
physical model and the figures.
"""

from __future__ import annotations

from collections.abc import Generator
from typing import Any, Literal, TypeVar, cast

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, PositiveFloat

from aatest.engine.errors import AnalysisError
from aatest.plugins.analysis.tfest import DiscreteTf, fit_discrete_tf, model_metrics

T = TypeVar("T")

MAX_POLES = 5
MIN_POINTS = 6
_FIT_TIE_PCT = 0.5
_SCAN_MAX_POLES = 2
#: a listed identification split needs this many points (a gain and a phase trend)
_MIN_IDENTIFICATION_POINTS = 2


class TransferFunctionOptions(BaseModel):
    """Model structures tried, the identification split and the anti-alias de-embedding.

    ``delay``: ``estimate`` tries every structure without a delay, with the cross-correlation
    delay and (n ≤ 2) with scanned integer delays; ``none`` only without. Every
    ``validation_every``-th FRF point (in frequency order) is kept for validation.
    ``antialias_hz``: the logger's pre-sample filter corner to de-embed from the physical
    model; ``auto`` finds it in the run metadata, ``none`` de-embeds nothing.
    ``identification_hz``: when given, the FRF points nearest these frequencies identify and
    all the others validate (the study's design: 7, 11, …, 27 Hz identify, the other whole
    frequencies 1–28 Hz validate); it replaces ``validation_every``.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)
    max_poles: int = Field(MAX_POLES, ge=0, le=8, description="largest n (zeros m ≤ n)")
    min_points: int = Field(MIN_POINTS, ge=MIN_POINTS, description="FRF points a group needs")
    delay: Literal["estimate", "none"] = "estimate"
    validation_every: int = Field(3, ge=2, description="every k-th point validates")
    antialias_hz: float | Literal["auto", "none"] = Field("auto", description="Hz, auto, none")
    identification_hz: tuple[PositiveFloat, ...] = Field(
        (), description="frequencies (Hz) whose nearest points identify; the rest validate")


#: identification and validation points (indices into the frequency-sorted FRF)
Split = tuple[np.ndarray, np.ndarray]


def _split(n_points: int, every: int = 3) -> Split:
    idx = np.arange(n_points)
    return idx[idx % every != every - 1], idx[idx % every == every - 1]


def split_points(f_hz: np.ndarray, options: TransferFunctionOptions) -> Split:
    """The identification/validation split of the (sorted) FRF frequencies ``f_hz``: the
    points nearest ``options.identification_hz`` identify when given, else every
    ``validation_every``-th point validates."""
    if not options.identification_hz:
        return _split(f_hz.size, options.validation_every)
    ident = np.unique([int(np.argmin(np.abs(f_hz - f))) for f in options.identification_hz])
    valid = np.setdiff1d(np.arange(f_hz.size), ident)
    if ident.size < _MIN_IDENTIFICATION_POINTS or valid.size < 1:
        raise AnalysisError(f"transfer function: identification_hz "
                            f"{list(options.identification_hz)} leaves {ident.size} "
                            f"identification and {valid.size} validation points")
    return ident, valid


def _candidate(f: np.ndarray, h: np.ndarray, n: int, m: int, d: int, source: str, dt: float,
               split: Split) -> tuple[DiscreteTf, dict[str, Any]]:
    ident, valid = split
    model = fit_discrete_tf(f[ident], h[ident], n, m, dt, d)
    metrics = model_metrics(model, f[ident], h[ident], f[valid], h[valid], source != "none")
    return model, {"n": n, "m": m, "delay_samples": d, "delay_source": source, **metrics}


def _rescanned(known: tuple[DiscreteTf, dict[str, Any]] | None
               ) -> tuple[DiscreteTf, dict[str, Any]] | None:
    """A fitted cross-correlation-delay candidate as the scan's row of the same delay."""
    return None if known is None else (known[0], {**known[1], "delay_source": "scan"})


def _usable(row: dict[str, Any]) -> bool:
    return row["stable"] and row["zeros_outside_unit_circle"] == 0 and np.isfinite(row["fit_pct"])


def _choose(rows: list[dict[str, Any]]) -> int:
    ok = [i for i, r in enumerate(rows) if _usable(r)] or list(range(len(rows)))
    best = max(rows[i]["fit_pct"] for i in ok)
    near = [i for i in ok if rows[i]["fit_pct"] >= best - _FIT_TIE_PCT]
    return min(near, key=lambda i: (rows[i]["n_params"], -rows[i]["fit_pct"]))


def estimate(f: np.ndarray, h: np.ndarray, dt: float, xcorr: dict[str, float],
             options: TransferFunctionOptions | None = None
             ) -> tuple[DiscreteTf, list[dict[str, Any]], int]:
    """All candidate models of one FRF; returns the chosen model, the table, its index."""
    return run_through(estimate_in_pieces(f, h, dt, xcorr, options))


#: a computation that pauses (yields) between its pieces and returns a ``T``
Pieces = Generator[None, None, T]


def run_through(pieces: Generator[Any, None, T]) -> T:
    """The value of a computation made in pieces (a generator pausing between them), made
    at once: the pass's way of calling what the early child makes piece by piece
    (:mod:`~aatest.plugins.analysis.tf_early`)."""
    while True:
        try:
            next(pieces)
        except StopIteration as done:
            return cast(T, done.value)


def estimate_in_pieces(f: np.ndarray, h: np.ndarray, dt: float, xcorr: dict[str, float],
                       options: TransferFunctionOptions | None = None
                       ) -> Pieces[tuple[DiscreteTf, list[dict[str, Any]], int]]:
    """:func:`estimate`, pausing after each candidate fit (a few ms each): the same
    operations in the same order. Why: the early-analysis child makes it between the steps
    it analyses (:mod:`~aatest.plugins.analysis.tf_early`)."""
    opts = options or TransferFunctionOptions()
    order = np.argsort(f)
    f, h = f[order], h[order]
    with_delay = opts.delay == "estimate"
    delays = [(0, "none")] + ([(int(xcorr["delay_samples"]), "xcorr")]
                              if xcorr["accepted"] and with_delay else [])
    split = split_points(f, opts)
    fitted = []
    for n in range(opts.max_poles + 1):
        for m in range(n + 1):
            for d, src in delays:
                fitted.append(_candidate(f, h, n, m, d, src, dt, split))
                yield
    plain = [r for _, r in fitted if r["delay_source"] == "none" and r["n"] <= _SCAN_MAX_POLES]
    top = int(xcorr["delay_samples"]) if with_delay else -1
    # the scan passes the cross-correlation delay too: that structure is fitted already (the
    # same fit and metrics, an estimated delay either way), only its source is "scan"
    done = {(r["n"], r["m"], r["delay_samples"]): (model, r) for model, r in fitted
            if r["delay_source"] == "xcorr"}
    for r in plain:
        for d in range(1, top + 2):
            fitted.append(_rescanned(done.get((r["n"], r["m"], d))) or
                          _candidate(f, h, r["n"], r["m"], d, "scan", dt, split))
            yield
    rows = [r for _, r in fitted]
    k = _choose(rows)
    return fitted[k][0], rows, k


def dc_gain(num: np.ndarray, den: np.ndarray) -> float:
    """G(0) of the continuous model num(s)/den(s) (``inf``/``nan`` where den(0) = 0).

    The very evaluation of python-control's ``TransferFunction(num, den).dcgain()`` (Horner at
    s = 0 as a complex array, the ratio's real part), without importing python-control: that
    import takes ≈ 0.4 s of CPU in every forked worker that fits a group, for one ratio.
    """
    s0 = np.zeros(1, dtype=complex)
    with np.errstate(all="ignore"):
        value = np.polyval(np.asarray(num, dtype=np.float64), s0) / \
            np.polyval(np.asarray(den, dtype=np.float64), s0)
    return float(np.real(value[0]))


def continuous_equivalent(model: DiscreteTf) -> dict[str, Any]:
    """Pole/zero-matched continuous model with ωn and ζ of its poles."""
    s_poles = model.continuous_poles()
    zeros = model.zeros()
    zeros = zeros[np.abs(np.angle(zeros)) < np.pi / 2]  # drop sampling zeros near z = −1
    s_zeros = np.log(zeros.astype(complex)) / model.dt
    num = np.atleast_1d(np.real(np.poly(s_zeros)))
    den = np.atleast_1d(np.real(np.poly(s_poles)))
    dc_discrete = complex(model.response(np.array([0.0]))[0])
    dc_cont = np.polyval(num, 0.0) / np.polyval(den, 0.0) if np.polyval(den, 0.0) else 1.0
    gain = float(np.real(dc_discrete / dc_cont)) if dc_cont else 1.0
    wn = np.abs(s_poles)
    return {"num": (gain * num).tolist(), "den": den.tolist(),
            "poles_rad_s": [[float(p.real), float(p.imag)] for p in s_poles],
            "natural_frequencies_hz": (wn / (2 * np.pi)).tolist(),
            "damping": (-np.real(s_poles) / np.where(wn > 0, wn, 1.0)).tolist(),
            "delay_s": model.delay_samples * model.dt, "dc_gain": dc_gain(gain * num, den)}
