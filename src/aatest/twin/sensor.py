"""The angular-accelerometer model: every contract effect applied to whole records at once.

Signal path of one sensor channel (docs/interfaces.md §4 vocabulary, same parameter names):

    α_top (table-top frame) ─ axis projection (misalignment, pivot, re-mount) ─ cross_axis
    ─ g_sensitivity ─ hysteresis (play) ─ rotor_stiction (a gap around the rate reversals)
    ─ sensor_dynamics (amplitude_damping) ─ saturation ─ resolution
    ─ nonlinearity_cubic ─ plugin effects in °/s² ─ scale (scale_temperature)
    ─ bias (bias_temperature) ─ jerk ─ jerk_distortion (on the dynamics' output)
    ─ plugin effects in V → volts

``time_delay`` is applied upstream by evaluating the motion at t − delay (exact for any delay,
no fractional-delay filter); white noise is added by the DAQ chain (see :mod:`daq`) so that
``noise_rms_v`` is the RMS the logger records.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from scipy import signal

from aatest.effects import EffectInputs, forward, load_effect
from aatest.twin.fastmath import standard_normal
from aatest.twin.model import AmplitudeDamping, BiasDrift, SensorModel
from aatest.twin.sensor_output import cubic, jerk_volts, volts_before_drift
from aatest.twin.zeta_blend import blend, filters_needed

#: damping-ratio grid of the amplitude-dependent dynamics: the output blends the two grid
#: filters around ζ(t) (a 0.02 step moves the 10 Hz gain of a 30 Hz sensor by < 0.01 dB)
_ZETA_STEP = 0.02
_ZETA_BOUNDS = (0.05, 5.0)


def play_operator(x: np.ndarray, half_width: float, y0: float | None = None) -> np.ndarray:
    """Backlash (play) operator y_k = min(x_k + r, max(x_k − r, y_{k−1})), vectorised.

    Each step is a clamp c_k(y) = clip(y, x_k − r, x_k + r); clamps compose into clamps
    (clip(clip(y, a, b), c, d) = clip(y, clip(a, c, d), clip(b, c, d))), so the whole sequence is
    an associative prefix scan done in ⌈log2 n⌉ vectorised passes (Hillis–Steele) instead of a
    per-sample Python loop: ≈ 17 passes for 2^17 samples.

    Parameters
    ----------
    x
        Input sequence (°/s²).
    half_width
        Play half width r ≥ 0 (°/s²).
    y0
        Initial output; default x[0] (the operator starts relaxed).
    """
    x = np.asarray(x, dtype=float)
    if half_width <= 0.0 or x.size == 0:
        return x.copy()
    lo, hi = x - half_width, x + half_width
    # each pass writes the composed clamps into the other pair of buffers (no temporaries)
    lo_next, hi_next = np.empty_like(lo), np.empty_like(hi)
    shift = 1
    while shift < x.size:
        # compose the clamp ending at k−shift (applied first) with the one ending at k
        lo_next[:shift], hi_next[:shift] = lo[:shift], hi[:shift]
        new_lo, new_hi = lo_next[shift:], hi_next[shift:]
        np.maximum(lo[:-shift], lo[shift:], out=new_lo)
        np.minimum(new_lo, hi[shift:], out=new_lo)
        np.maximum(hi[:-shift], lo[shift:], out=new_hi)
        np.minimum(new_hi, hi[shift:], out=new_hi)
        lo, hi, lo_next, hi_next = lo_next, hi_next, lo, hi
        shift *= 2
        # once every window of `shift` samples pins the output (lo == hi), earlier history
        # no longer matters: stop (typically after 4–6 passes instead of 17)
        if np.array_equal(lo[shift:], hi[shift:]):
            break
    start = x[0] if y0 is None else y0
    return np.minimum(np.maximum(start, lo), hi)


@lru_cache(maxsize=64)
def dynamics_filter(natural_frequency_hz: float, damping: float, dt_s: float) -> tuple:
    """(b, a) of H(s) = ωn²/(s² + 2ζωn s + ωn²) by the bilinear transform.

    Frequency warping at 2 kHz is < 0.1 % for ωn ≤ 100 Hz, far inside the FRF tolerances.
    """
    wn = 2 * np.pi * natural_frequency_hz
    return signal.bilinear([wn * wn], [1.0, 2 * damping * wn, wn * wn], fs=1.0 / dt_s)


@lru_cache(maxsize=16)
def band_filter(corner_hz: float, dt_s: float) -> tuple:
    """(b, a) of the 4th-order Butterworth low-pass that bounds the amplitude's band."""
    nyquist = 0.5 / dt_s
    return signal.butter(4, min(corner_hz, 0.9 * nyquist), fs=1.0 / dt_s)


def unit_steady_state(b: np.ndarray, a: np.ndarray) -> np.ndarray:
    """``scipy.signal.lfilter_zi(b, a)`` (read-only), solved once per filter: every step
    starts a dozen filters from steady state, and each solve builds a companion system."""
    b, a = np.asarray(b, dtype=np.float64), np.asarray(a, dtype=np.float64)
    return _unit_steady_state(b.tobytes(), a.tobytes())


@lru_cache(maxsize=256)
def _unit_steady_state(b: bytes, a: bytes) -> np.ndarray:
    zi = signal.lfilter_zi(np.frombuffer(b), np.frombuffer(a))
    zi.flags.writeable = False
    return zi


def lowpass(x: np.ndarray, b: np.ndarray, a: np.ndarray) -> np.ndarray:
    """Filter starting in steady state at the first sample (no start-up transient)."""
    zi = unit_steady_state(b, a) * x[0]
    return signal.lfilter(b, a, x, zi=zi)[0]


def lowpass_carry(x: np.ndarray, b: np.ndarray, a: np.ndarray, key: str,
                  state: ChannelState | None) -> np.ndarray:
    """:func:`lowpass` of one block of a longer record, continuing the filter state of the
    previous block (kept in ``state`` under ``key``); the first block starts in steady state,
    so a record filtered block by block is the record filtered at once."""
    if state is None:
        return lowpass(x, b, a)
    zi = state.filters.get(key)
    if zi is None:
        zi = unit_steady_state(b, a) * x[0]
    y, state.filters[key] = signal.lfilter(b, a, x, zi=zi)
    return np.asarray(y)


def trailing_amplitude(x: np.ndarray, window: int, state: ChannelState | None) -> np.ndarray:
    """√2·RMS of ``x`` over the trailing ``window`` samples (fewer at the record's start),
    continuing the previous block's tail kept in ``state`` (cumulative sums, no loop)."""
    sq = np.asarray(x, dtype=np.float64) ** 2
    tail = state.filters.get("amplitude_tail") if state is not None else None
    full = sq if tail is None else np.concatenate([tail, sq])
    csum = np.empty(full.size + 1)
    csum[0] = 0.0
    np.cumsum(full, out=csum[1:])
    if state is not None:
        state.filters["amplitude_tail"] = full[-max(window - 1, 1):]
    # window sums csum[end] − csum[start], end = m + 1 … size, start = max(end − window, 0),
    # divided by end − start: by slices (the first `short` windows start at 0)
    m = full.size - sq.size
    short = max(0, min(window, full.size) - m)
    out = np.empty(sq.size)
    np.subtract(csum[m + 1: m + 1 + short], csum[0], out=out[:short])
    np.subtract(csum[m + 1 + short:], csum[m + 1 + short - window: full.size + 1 - window],
                out=out[short:])
    out *= 2.0
    out[:short] /= np.arange(m + 1, m + 1 + short)
    out[short:] /= window
    return np.sqrt(out, out=out)


def damping_of(effect: AmplitudeDamping, damping: float, amplitude_dps2: np.ndarray
               ) -> np.ndarray:
    """ζ(A) of :class:`AmplitudeDamping` around the sensor's ``damping``, within bounds."""
    floor = effect.floor_dps2 if effect.floor_dps2 is not None else 1e-9
    # damping + c·log10(max(A, floor)/ref), clipped: in one buffer (a·b, a + b commute)
    if np.ndim(amplitude_dps2) == 0:  # a scalar amplitude: the plain formula
        ratio = np.maximum(amplitude_dps2, floor) / effect.reference_dps2
        return np.clip(damping + effect.damping_per_decade * np.log10(ratio), *_ZETA_BOUNDS)
    zeta = np.maximum(amplitude_dps2, floor)
    zeta /= effect.reference_dps2
    np.log10(zeta, out=zeta)
    zeta *= effect.damping_per_decade
    zeta += damping
    return np.clip(zeta, *_ZETA_BOUNDS, out=zeta)


def amplitude_dynamics(model: SensorModel, alpha: np.ndarray, dt_s: float,
                       state: ChannelState | None) -> np.ndarray:
    """``sensor_dynamics`` with the amplitude-dependent damping ``amplitude_damping``.

    ζ(t) follows the sensed amplitude; the output blends, sample by sample, the outputs of
    the fixed-ζ filters on a 0.02 grid either side of ζ(t) (each carrying its own state), so
    a steady sine sees the linear filter of its amplitude's damping.
    """
    dyn, eff = model.sensor_dynamics, model.amplitude_damping
    assert dyn is not None and eff is not None
    b, a = band_filter(eff.band_hz, round(dt_s, 15))
    band = lowpass_carry(alpha, b, a, "amplitude_band", state)
    amplitude = trailing_amplitude(band, max(round(eff.window_s / dt_s), 1), state)
    grid = damping_of(eff, dyn.damping, amplitude)
    grid /= _ZETA_STEP
    low = np.floor(grid).astype(np.int64)
    frac = np.subtract(grid, low, out=grid)
    # sample i takes 1 − frac_i of the ζ-grid filter low_i and frac_i of filter low_i + 1:
    # a filter is run only up to the last sample that uses it when no later block continues it
    k0, needed = filters_needed(low, frac)
    filtered: dict[int, np.ndarray] = {}  # row → output of filter k0 + row (a prefix)
    used = set()
    for row in np.flatnonzero(needed >= 0):
        k = k0 + int(row)
        b, a = dynamics_filter(dyn.natural_frequency_hz, round(k * _ZETA_STEP, 6),
                               round(dt_s, 15))
        used.add(f"dynamics:{k}")
        stop = alpha.size if state is not None and not state.final else int(needed[row]) + 1
        filtered[int(row)] = lowpass_carry(alpha[:stop], b, a, f"dynamics:{k}", state)
    if state is not None:  # a filter idle for a block would resume from a stale state
        for key in [k for k in state.filters if k.startswith("dynamics:") and k not in used]:
            del state.filters[key]
    return blend(filtered, low - k0, frac)


@dataclass
class ChannelState:
    """What one sensor channel carries from one generation block of a record to the next.

    ``filters`` holds lfilter states by stage; ``play_v`` the hysteresis output; the drift
    terms their last values (V); ``drift_rng`` draws the drift increments, a stream of its own
    so switching the drift on leaves every other noise realisation unchanged; ``elapsed_s``
    is the time since the record's first sample.
    """

    filters: dict[str, np.ndarray] = field(default_factory=dict)
    play_dps2: float | None = None
    walk_v: float = 0.0
    markov_v: float = 0.0
    elapsed_s: float = 0.0
    drift_rng: np.random.Generator | None = None
    #: no later block continues this one: filters may stop at the last sample they feed
    final: bool = False


def bias_drift_v(drift: BiasDrift, n: int, dt_s: float, state: ChannelState) -> np.ndarray:
    """Bias wander (V) over the next ``n`` samples: linear rate + random walk + Gauss–Markov.

    Vectorised: the walk is a cumulative sum, the first-order Gauss–Markov process an lfilter
    (x_k = φ·x_{k−1} + √(1−φ²)·σ·w_k), both continued from ``state``. All three start at 0 at
    the record's first sample: ``bias_v`` is the bias then, the drift what follows.
    """
    rng = state.drift_rng if state.drift_rng is not None else np.random.default_rng(0)
    state.drift_rng = rng
    # rate·(elapsed + dt·k)/3600 + walk + Gauss–Markov, in place (a + b, a·b commute)
    out = np.arange(n, dtype=np.float64)
    out *= dt_s
    out += state.elapsed_s
    out *= drift.rate_v_per_h
    out /= 3600.0
    if drift.random_walk_v_per_sqrt_s > 0.0:
        walk = standard_normal(rng, n)
        walk *= drift.random_walk_v_per_sqrt_s * np.sqrt(dt_s)
        np.cumsum(walk, out=walk)
        walk += state.walk_v
        state.walk_v = float(walk[-1])
        out += walk
    if drift.instability_v > 0.0:
        phi = float(np.exp(-dt_s / drift.correlation_s))
        w = standard_normal(rng, n)
        w *= np.sqrt(1.0 - phi * phi) * drift.instability_v
        markov, _ = signal.lfilter([1.0], [1.0, -phi], w, zi=[phi * state.markov_v])
        state.markov_v = float(markov[-1])
        out += markov
    state.elapsed_s += dt_s * n
    return np.asarray(out, dtype=float)


@dataclass(frozen=True)
class SensorInputs:
    """What one sensor experiences over a record, on the DAQ sample grid.

    alpha_top_dps2 : (3, n) angular acceleration of the table top (already delayed).
    up_g : (3, n) specific force of gravity (g) in the table-top frame.
    temperature_c : (n,) sensor temperature.
    axes : (3, 3) sensor x, y, z axes as columns, in table-top coordinates.
    dt_s : sample spacing in lab seconds.
    time_s : (n,) lab time since the table record started (s), for time-dependent plugin
        effects; None: since the first sample.
    rate_top_dps : (3, n) angular velocity of the table top (already delayed), °/s; needed
        by ``rotor_stiction`` only.
    """

    alpha_top_dps2: np.ndarray
    up_g: np.ndarray
    temperature_c: np.ndarray
    axes: np.ndarray
    dt_s: float
    time_s: np.ndarray | None = None
    rate_top_dps: np.ndarray | None = None


def sensed_acceleration(model: SensorModel, inp: SensorInputs,
                        state: ChannelState | None = None) -> np.ndarray:
    """Acceleration the sensing element responds to, before dynamics (°/s²).

    ``state`` continues the hysteresis of the previous block of a record generated in blocks.
    """
    if model.cross_axis is not None:  # one projection on a blended axis: z + r_x·x + r_y·y
        cx, cy = model.cross_axis.ratio_x, model.cross_axis.ratio_y
        axis = inp.axes[:, 2] + cx * inp.axes[:, 0] + cy * inp.axes[:, 1]
    else:
        axis = inp.axes[:, 2]
    alpha = axis @ inp.alpha_top_dps2
    if model.g_sensitivity is not None:
        along = inp.axes[:, 2] @ inp.up_g
        along *= model.g_sensitivity.coefficient_dps2_per_g
        alpha += along
    if model.hysteresis is not None:
        start = state.play_dps2 if state is not None else None
        alpha = play_operator(alpha, model.hysteresis.half_width_dps2, start)
        if state is not None and alpha.size:
            state.play_dps2 = float(alpha[-1])
    return alpha


def stiction_gate(model: SensorModel, inp: SensorInputs) -> np.ndarray:
    """1 where the rotor moves, 1 − ``depth`` where it sticks to the case (``rotor_stiction``):
    the case's rate about the sensor axis within ±``breakaway_rate_dps`` of zero."""
    assert model.rotor_stiction is not None
    assert inp.rate_top_dps is not None, "rotor_stiction needs the table top's rate"
    stiction = model.rotor_stiction
    rate = inp.axes[:, 2] @ inp.rate_top_dps
    return 1.0 - stiction.depth * (np.abs(rate) < stiction.breakaway_rate_dps)


def output_volts(model: SensorModel, inp: SensorInputs, t_ref_c: float,
                 state: ChannelState | None = None) -> np.ndarray:
    """Sensor output voltage before the DAQ's filter, white noise and ADC (V).

    ``state`` carries the filter, hysteresis and bias-drift states from the previous block when
    a long record is generated block by block (:mod:`aatest.twin.synthesis`); the bias drift
    (``bias_drift``, a random process of its own stream) is only generated with a state.
    """
    sensed = sensed_acceleration(model, inp, state)
    alpha = sensed if model.rotor_stiction is None else sensed * stiction_gate(model, inp)
    if model.sensor_dynamics is not None and model.amplitude_damping is not None:
        alpha = amplitude_dynamics(model, alpha, inp.dt_s, state)
    elif model.sensor_dynamics is not None:
        b, a = dynamics_filter(model.sensor_dynamics.natural_frequency_hz,
                               model.sensor_dynamics.damping, round(inp.dt_s, 15))
        alpha = lowpass_carry(alpha, b, a, "dynamics", state)
    response = alpha
    if model.saturation is not None:
        lim = model.saturation.limit_dps2
        alpha = np.clip(alpha, -lim, lim)
    if model.resolution_dps2 > 0.0:
        counts = np.divide(alpha, model.resolution_dps2)  # round(α/res)·res, in one buffer
        np.round(counts, out=counts)
        counts *= model.resolution_dps2
        alpha = counts
    d_temp = inp.temperature_c - t_ref_c
    if model.plugin_effects:  # (their inputs only when there are some: time_s is a pass)
        time_s = inp.time_s if inp.time_s is not None else np.arange(alpha.size) * inp.dt_s
        plugin_inputs = EffectInputs(alpha, sensed, d_temp, time_s, inp.dt_s, model.range_dps2)
    if model.nonlinearity_cubic is not None:
        alpha = cubic(alpha, model.nonlinearity_cubic.c3, model.range_dps2)
    plugin_volts: np.ndarray | None = None  # Σ of the plugin terms in V, from zeros
    for pe in model.plugin_effects or ():
        installed = load_effect(pe.effect, pe.distribution)
        term = forward(installed, plugin_inputs, pe.parameters)
        if installed.effect.enters == "acceleration":
            alpha = alpha + term
        else:
            plugin_volts = (np.zeros_like(alpha) if plugin_volts is None else plugin_volts) + term
    volts = volts_before_drift(model, alpha, d_temp)
    if model.bias_drift is not None and state is not None:
        volts += bias_drift_v(model.bias_drift, volts.size, inp.dt_s, state)
    volts += jerk_volts(model, sensed, response, inp.dt_s)
    volts += 0.0 if plugin_volts is None else plugin_volts  # (+ 0.0: as adding the zeros)
    return volts
