"""Table effect: position-periodic rate ripple (motor vibration: :mod:`.vibration`).

Both are real motion, so the table's own position log departs from the command exactly as the
sensor does (docs/interfaces.md §4 "Table effects"). Their parameters are read from the table log
(the encoder sees them with arc-second noise) and the sensor provides the evidence: the
residual variance the motion explains. Ripple frequencies scale with the rate (n cycles per
degree); a motor line stays at one frequency whatever the motion, and is present at rest.
"""

from __future__ import annotations

import numpy as np
from scipy import optimize

from aatest.diagnose.candidates.base import Z95, CandidateFit, Context, replace_spec
from aatest.diagnose.periodogram import lomb_scargle_power
from aatest.diagnose.replay import StepReplay, ripple_regressors
from aatest.numerics import TINY

#: ripple search range, cycles per degree
RIPPLE_CPD = (0.2, 6.0)
#: a line must stand this far above the median spectral level of the table log
LINE_SNR = 25.0
#: a ripple must explain this share of the table-log deviation variance
RIPPLE_MIN_SHARE = 0.05
_DECIMATE = 4
#: a ripple line within this many cycles/° of one already found is that line again
KNOWN_LINE_CPD = 0.05
#: cycles/° grid on which the constant-rate spectra are compared
_CPD_GRID = 0.001


def _moving(ctx: Context) -> list[StepReplay]:
    return [s for s in ctx.replay.steps if s.inner.moving]


def testable_ripple(ctx: Context) -> str | None:
    return None if _moving(ctx) else "the inner axis never moves (constant-rate steps needed)"


def _columns(s: StepReplay, ns: tuple[float, ...], step: int = 1) -> np.ndarray:
    """Form-projected ripple position regressors of one step for every n in ``ns``."""
    cols = []
    for n in ns:
        ps, pc, _, _ = ripple_regressors(s, s.time_s, n)
        cols += [ps[::step], pc[::step]]
    return np.column_stack(cols) if cols else np.zeros((s.time_s[::step].size, 0))


def _fit_table(steps: list[StepReplay], ns: tuple[float, ...]
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(coefficients, residual, centred deviation) of the ripple lines ``ns`` on the table log."""
    x = np.concatenate([_columns(s, ns, _DECIMATE) for s in steps])
    dev = np.concatenate([s.table_deviation_deg["inner"][::_DECIMATE] for s in steps])
    dev = dev - dev.mean()
    if x.shape[1] == 0:
        return np.zeros(0), dev, dev
    coef, *_ = np.linalg.lstsq(x, dev, rcond=None)
    return coef, dev - x @ coef, dev


def _ripple_sse(steps: list[StepReplay], n_cpd: float, known: tuple[float, ...]) -> float:
    _, resid, _ = _fit_table(steps, (*known, n_cpd))
    return float(resid @ resid)


def _remaining(steps: list[StepReplay], known: tuple[float, ...]) -> list[np.ndarray]:
    """Per-step table deviation with the already-known ripple lines removed (full rate)."""
    coef, _, _ = _fit_table(steps, known)
    return [s.table_deviation_deg["inner"] - (_columns(s, known) @ coef if known else 0.0)
            for s in steps]


def _ripple_seed(steps: list[StepReplay], known: tuple[float, ...]) -> tuple[float, float]:
    """(cycles/°, search half width) of the strongest new position-periodic line.

    Constant-rate steps sample the angle uniformly, so an FFT of their deviation gives the
    line at f = n·rate directly; sine steps need a Lomb–Scargle periodogram over the angle.
    Lines already in the model are removed first and masked.
    """
    devs = _remaining(steps, known)
    ramps = [i for i, s in enumerate(steps) if s.inner.rate_dps and not s.inner.frequency_hz]
    if ramps:
        # each ramp's spectrum on a cycles-per-degree axis, relative to its own median level;
        # a position-periodic line sits at the same cycles/° at every rate, a motor line at the
        # same Hz: the minimum over ramps of different rates keeps the first, drops the second
        grid = np.arange(RIPPLE_CPD[0], RIPPLE_CPD[1], _CPD_GRID)
        levels, widths = [], []
        for i in ramps:
            s, dev = steps[i], devs[i] - devs[i].mean()
            spec = np.abs(np.fft.rfft(dev * np.hanning(dev.size))) ** 2
            rate = abs(s.inner.rate_dps)
            cpd = np.fft.rfftfreq(dev.size, s.dt_s) / rate
            inside = (cpd >= RIPPLE_CPD[0]) & (cpd <= RIPPLE_CPD[1])
            floor = max(float(np.median(spec[inside])), TINY) if inside.any() else 1.0
            levels.append(np.interp(grid, cpd, spec / floor))
            widths.append(2.0 / (dev.size * s.dt_s * rate))
        rates = {round(abs(steps[i].inner.rate_dps), 6) for i in ramps}
        combined = np.min(levels, axis=0) if len(rates) > 1 else np.max(levels, axis=0)
        for k in known:
            combined[np.abs(grid - k) <= KNOWN_LINE_CPD] = 0.0
        return float(grid[int(np.argmax(combined))]), max(widths)
    theta = np.concatenate([s.inner.evaluate(s.time_s[::_DECIMATE])[0] for s in steps])
    dev = np.concatenate([d[::_DECIMATE] for d in devs])
    grid = np.arange(RIPPLE_CPD[0], RIPPLE_CPD[1], 0.01)
    power = lomb_scargle_power(theta, dev - dev.mean(), 2 * np.pi * grid)
    for k in known:
        power[np.abs(grid - k) <= KNOWN_LINE_CPD] = 0.0
    return float(grid[int(np.argmax(power))]), 0.01


def ripple_from_table(steps: list[StepReplay], known: tuple[float, ...] = ()
                      ) -> tuple[float, float, float, float, float]:
    """(cycles/°, amplitude °, its u °, share of the remaining deviation variance, phase rad).

    Fitted on the table's position log together with the lines already known.
    """
    n0, width = _ripple_seed(steps, known)
    _, before, _ = _fit_table(steps, known)
    total = float(before @ before)
    if total <= 0.0 or _ripple_sse(steps, n0, known) > (1.0 - 0.5 * RIPPLE_MIN_SHARE) * total:
        return n0, 0.0, 0.0, 0.0, 0.0  # no position-periodic line to refine
    res = optimize.minimize_scalar(lambda n: _ripple_sse(steps, n, known),
                                   bounds=(max(n0 - width, RIPPLE_CPD[0]), n0 + width),
                                   method="bounded", options={"xatol": 1e-7})
    n = float(res.x)
    coef, resid, _ = _fit_table(steps, (*known, n))
    share = 1.0 - float(resid @ resid) / total
    a_sin, a_cos = coef[-2], coef[-1]
    sigma = float(np.sqrt(resid @ resid / max(resid.size - coef.size, 1)))
    u = sigma * np.sqrt(2.0 / resid.size)
    # a·sin(kθ + φ) = a·cos φ·sin kθ + a·sin φ·cos kθ
    return n, float(np.hypot(a_sin, a_cos)), u, share, float(np.arctan2(a_cos, a_sin))


def fit_ripple(ctx: Context) -> CandidateFit:
    steps = _moving(ctx)
    known = ctx.current.spec.ripple_cpd
    n, amp, u, share, phase = ripple_from_table(steps, known)
    if share < RIPPLE_MIN_SHARE or amp < 5 * u:
        out = CandidateFit("rate_ripple", ctx.current, {"cycles_per_deg": n, "amplitude_deg": amp},
                           {}, attributed_to="table")
        out.veto = "the table log shows no (further) position-periodic error"
        return out
    n_round = round(n, 4)
    # a·sin(kθ + φ) = a·cos φ·sin kθ + a·sin φ·cos kθ: the line as real motion of the table
    motion = (n_round, round(amp * float(np.cos(phase)), 12), round(amp * float(np.sin(phase)), 12))
    fit = ctx.fit(replace_spec(ctx.current.spec, ripple_cpd=(*known, n_round),
                               ripple_motion_deg=(*ctx.current.spec.ripple_motion_deg, motion)))
    params = {"cycles_per_deg": n_round, "amplitude_deg": amp}
    ci = {"cycles_per_deg": [n_round, n_round], "amplitude_deg": [amp - Z95 * u, amp + Z95 * u]}
    sine, cosine = fit.value(f"ripple{n_round:g}_s"), fit.value(f"ripple{n_round:g}_c")
    sensor_amp = float(np.hypot(sine, cosine) / ctx.scale_of(fit))
    return CandidateFit("rate_ripple", fit, params, ci, attributed_to="table",
                        extra={"phase_rad": phase, "amplitude_deg_seen_by_sensor": sensor_amp,
                               "table_log_share": share})
