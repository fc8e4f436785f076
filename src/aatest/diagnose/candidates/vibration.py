"""Table effect: narrow-band motor vibration, one tone or a band of tones.

The vibration is real axis acceleration while the motor is on, so the table's position log
shows it (angle −A/(2πf)²·sin) as plainly as the sensor. Lines are read from the table log at
rest when there is such a step (nothing else moves then), strongest first; further lines
within :data:`BAND_SEARCH_HZ` of the first make a band. The reported peak acceleration is the
band's RMS-equivalent single tone, √ΣA_k², at the power-weighted mean frequency.
"""

from __future__ import annotations

import numpy as np
from scipy import optimize, signal

from aatest.diagnose.candidates.base import Z95, CandidateFit, Context, replace_spec
from aatest.diagnose.replay import StepReplay

#: a line must stand this far above the median spectral level of the table log
LINE_SNR = 25.0
MAX_TONES = 6
BAND_SEARCH_HZ = 10.0
#: spectral bins either side of a known tone masked in the search for the next one
KNOWN_TONE_BINS = 1.5
_NPERSEG = 4096
#: lines below this (Hz) are motion, not vibration
MIN_LINE_HZ = 5.0
#: relative standard uncertainty of an amplitude seen in one step only
DEFAULT_REL_U = 0.05


def _linear_detrend(x: np.ndarray) -> np.ndarray:
    """Remove a straight line (what ``detrend="linear"`` does; scipy-stubs mistype that name)."""
    return np.asarray(signal.detrend(x, type="linear"))


def testable_vibration(ctx: Context) -> str | None:
    on = [s for s in ctx.replay.steps if s.motor_on]
    return None if on else "the motor is never on"


def _steps(ctx: Context) -> list[StepReplay]:
    on = [s for s in ctx.replay.steps if s.motor_on]
    return [s for s in on if not s.inner.moving and not s.outer.moving] or on


def _design(t: np.ndarray, freqs: list[float]) -> np.ndarray:
    cols = [np.ones_like(t), t]
    for f in freqs:
        w = 2 * np.pi * f
        cols += [np.sin(w * t), np.cos(w * t)]
    return np.column_stack(cols)


def _fit_step(s: StepReplay, freqs: list[float]) -> tuple[np.ndarray, np.ndarray]:
    """(coefficients, residual) of offset, trend and the tones on one step's deviation."""
    dev = s.table_deviation_deg["inner"]
    t = s.time_s
    x = _design(t - t.mean(), freqs)  # centred time keeps the normal equations well scaled
    gram = x.T @ x
    coef = np.linalg.solve(gram + 1e-12 * np.trace(gram) * np.eye(gram.shape[0]), x.T @ dev)
    return coef, dev - x @ coef


def _sse(steps: list[StepReplay], freqs: list[float]) -> float:
    return float(sum(float(r @ r) for r in (_fit_step(s, freqs)[1] for s in steps)))


def _peak(steps: list[StepReplay], freqs: list[float], fs: float,
          near: float | None) -> tuple[float, float] | None:
    """(f, SNR) of the strongest line left in the deviation (near ``near`` when given)."""
    if not steps:
        return None
    spectra = [signal.welch(_fit_step(s, freqs)[1], fs=fs, nperseg=min(_NPERSEG, s.n))
               for s in steps]
    f = spectra[0][0]
    total = np.sum([p for _, p in spectra], axis=0)
    band = (f > MIN_LINE_HZ) & (f < 0.4 * fs)
    floor = float(np.median(total[band])) if band.any() else 0.0
    if near is not None:
        band &= np.abs(f - near) <= BAND_SEARCH_HZ
    for known in freqs:
        # known tones are fitted out of the residual already; their 1.5 bins stay masked (a
        # wider mask hid the neighbours of a band's strongest tone: its power went missing)
        band &= np.abs(f - known) > KNOWN_TONE_BINS * (f[1] - f[0])
    if not band.any():
        return None
    i = int(np.flatnonzero(band)[np.argmax(total[band])])
    if total[i] <= 0.0:
        return None
    return float(f[i]), float(total[i] / floor) if floor > 0 else float("inf")


def vibration_lines(steps: list[StepReplay], fs: float) -> list[float]:
    """Frequencies of the motor line(s) in the table log, strongest first (empty: none)."""
    freqs: list[float] = []
    while len(freqs) < MAX_TONES:
        peak = _peak(steps, freqs, fs, freqs[0] if freqs else None)
        if peak is None or peak[1] < LINE_SNR:
            break
        df = fs / _NPERSEG
        res = optimize.minimize_scalar(lambda f: _sse(steps, [*freqs, f]),
                                       bounds=(peak[0] - df, peak[0] + df), method="bounded",
                                       options={"xatol": 1e-5})
        freqs.append(float(res.x))
    return _refine(steps, freqs, fs) if len(freqs) > 1 else freqs


def _refine(steps: list[StepReplay], freqs: list[float], fs: float, passes: int = 1) -> list[float]:
    """Coordinate-wise refinement of close tones: each one re-fitted with the others present."""
    df = 0.5 * fs / _NPERSEG
    freqs = list(freqs)
    for _ in range(passes):
        for j in range(len(freqs)):
            def cost(f: float, j: int = j) -> float:
                return _sse(steps, [*freqs[:j], f, *freqs[j + 1:]])

            freqs[j] = float(optimize.minimize_scalar(
                cost, bounds=(freqs[j] - df, freqs[j] + df), method="bounded",
                options={"xatol": 1e-5}).x)
    return freqs


def band_amplitude(steps: list[StepReplay], lo_hz: float, hi_hz: float, fs: float
                   ) -> tuple[float, float]:
    """(peak-equivalent amplitude °/s², its u) from the band power of the table log.

    Parseval: the acceleration variance in [lo, hi] is Σ A_k²/2 however close the tones are,
    so √(2·variance) is the peak of the one tone with the band's power (the twin's convention).
    """
    values = []
    for s in steps:
        f, p = signal.periodogram(s.table_deviation_deg["inner"], fs=fs, window="hann",
                                  detrend=_linear_detrend)
        ok = (f > MIN_LINE_HZ) & (f < 0.4 * fs)
        floor = float(np.median(p[ok])) if ok.any() else 0.0
        band = (f >= lo_hz) & (f <= hi_hz)
        var = float(np.sum((p[band] - floor) * (2 * np.pi * f[band]) ** 4) * (f[1] - f[0]))
        values.append(max(var, 0.0))
    v = np.asarray(values)
    amp = float(np.sqrt(2.0 * v.mean()))
    if v.size > 1 and amp > 0:
        u = float(np.sqrt(2.0) * v.std(ddof=1) / np.sqrt(v.size) / (2 * amp))
    else:
        u = DEFAULT_REL_U * amp
    return amp, u


def tone_amplitudes(steps: list[StepReplay], freqs: list[float]) -> np.ndarray:
    """Peak acceleration of every tone in every step, (steps, tones) °/s²."""
    w2 = (2 * np.pi * np.asarray(freqs)) ** 2
    coefs = np.array([_fit_step(s, freqs)[0][2:] for s in steps]).reshape(len(steps), -1, 2)
    return np.hypot(coefs[..., 0], coefs[..., 1]) * w2


def fit_vibration(ctx: Context) -> CandidateFit:
    steps = _steps(ctx)
    freqs = vibration_lines(steps, 1.0 / ctx.replay.dt_s)
    if not freqs:
        out = CandidateFit("motor_vibration", ctx.current,
                           {"frequency_hz": 0.0, "amplitude_dps2": 0.0}, {}, attributed_to="table")
        out.veto = "the table log shows no narrow-band line"
        return out
    fs = 1.0 / ctx.replay.dt_s
    amps = tone_amplitudes(steps, freqs)
    power = np.mean(amps**2, axis=0)
    k = len(freqs)
    if k > 1:  # a band: its power, not the (possibly unresolved) tones, gives the amplitude
        margin = 4.0 * fs / min(s.n for s in steps)
        total, u = band_amplitude(steps, min(freqs) - margin, max(freqs) + margin, fs)
    else:
        total = float(np.sqrt(power.sum()))
        per_step = np.sqrt(np.sum(amps**2, axis=1))
        u = (float(per_step.std(ddof=1) / np.sqrt(per_step.size)) if per_step.size > 1
             else DEFAULT_REL_U * total)
    f_mean = float(np.sum(power * np.asarray(freqs)) / power.sum())
    bandwidth = (max(freqs) - min(freqs)) * (k + 1) / (k - 1) if k > 1 else 0.0
    fit = ctx.fit(replace_spec(ctx.current.spec, vibration_hz=tuple(round(f, 5) for f in freqs)))
    return CandidateFit("motor_vibration", fit, {"frequency_hz": f_mean, "amplitude_dps2": total},
                        {"frequency_hz": [min(freqs), max(freqs)] if k > 1 else [f_mean, f_mean],
                         "amplitude_dps2": [total - Z95 * u, total + Z95 * u]},
                        attributed_to="table",
                        extra={"bandwidth_hz": bandwidth, "tones_hz": freqs,
                               "tone_amplitudes_dps2": [float(a) for a in np.sqrt(power)]})
