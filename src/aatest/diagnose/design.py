"""The extended sensor model as a design matrix: shape parameters plus linear terms.

A model *spec* names the effects switched on. Nonlinear ("shape") parameters — delay,
dynamics, hysteresis, saturation, clock warp, ripple and vibration frequencies — transform
the commanded motion; everything else enters linearly, as one or two columns scaled by the
sensor's scale factor K, so for fixed shape parameters the whole model is one least-squares
problem. The order of the signal path is the twin's (``aatest.twin.sensor``):

    α(t − delay) → hysteresis → stiction gap → dynamics → saturation → cubic → K(T) → + b(T)
    + jerk → logger filter

The model's records are in :mod:`aatest.diagnose.spec`, its least squares on Gram matrices in
:mod:`aatest.diagnose.gram`.
"""

from __future__ import annotations

from dataclasses import replace
from functools import lru_cache

import numpy as np
from scipy import signal

from aatest.diagnose.gram import Fit
from aatest.diagnose.replay import (
    PAD_SAMPLES,
    Replay,
    StepReplay,
    gravity_along,
    ripple_regressors,
    sensor_acceleration,
    sensor_axes,
    sensor_rate,
)
from aatest.diagnose.spec import ChannelInfo, Spec
from aatest.diagnose.steady_state import response, tone_columns
from aatest.effects import EffectInputs, design_column_names, design_columns
from aatest.twin.daq import antialias_filter
from aatest.twin.kinematics import E_I
from aatest.twin.model import AmplitudeDamping
from aatest.twin.sensor import band_filter, damping_of, play_operator

#: unshifted vibration tones (sin and cos on the record grid) kept per step
TONE_MEMO = 12


def column_names(spec: Spec, replay: Replay) -> list[str]:
    """Names of the design columns of ``spec`` (bias and scale always first)."""
    names = ["bias", "scale"]
    for name in ("bias_temperature", "scale_temperature", "nonlinearity_cubic",
                 "jerk_sensitivity", "g_sensitivity", "jerk_distortion"):
        if name in spec.linear:
            names.append(name)
    if "cross_axis" in spec.linear:
        names += ["cross_x", "cross_y"]
    if "rotor_stiction" in spec.linear:
        names.append("rotor_stiction")
    names += design_column_names(spec.linear)  # plugin effects (aatest.effects)
    for n in spec.ripple_cpd:
        names += [f"ripple{n:g}_s", f"ripple{n:g}_c"]
    for s in replay.steps:
        for j in range(len(spec.vibration_hz)):
            names += [f"vib{s.index}_{j}_s", f"vib{s.index}_{j}_c"]
    return names


@lru_cache(maxsize=8)
def _aa(corner_hz: float, dt_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(b, a, unit steady-state initial conditions) of the logger's pre-sample filter."""
    b, a, _ = antialias_filter(corner_hz, dt_s)
    return b, a, signal.lfilter_zi(b, a)


@lru_cache(maxsize=64)
def _dyn(natural_frequency_hz: float, damping: float, dt_s: float
         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(b, a, unit steady-state initial conditions) of the sensor's second-order dynamics.

    The twin's filter (:func:`aatest.twin.sensor.dynamics_filter`: ωn²/(s² + 2ζωn s + ωn²)
    by the bilinear transform) in closed form: a dynamics search meets a new (ωn, ζ) on
    almost every evaluation, and SciPy's general polynomial route and ``lfilter_zi`` cost
    about a millisecond each per filter; these are the same numbers to rounding (tested).
    With k = 2/dt (s = k·(1 − z⁻¹)/(1 + z⁻¹)):

        b = ωn²·(1, 2, 1) / a0,   a = (a0, 2ωn² − 2k², k² − 2ζωn·k + ωn²) / a0,
        a0 = k² + 2ζωn·k + ωn²
    """
    wn = 2 * np.pi * natural_frequency_hz
    k = 2.0 / dt_s
    k2, wn2, cross = k * k, wn * wn, 2.0 * damping * wn * k
    a0 = k2 + cross + wn2
    b = np.array([wn2, 2.0 * wn2, wn2]) / a0
    a = np.array([1.0, (2.0 * wn2 - 2.0 * k2) / a0, (k2 - cross + wn2) / a0])
    # steady state of lfilter's transposed direct form under a unit input (lfilter_zi):
    # (I − Aᵀ)·zi = b[1:] − a[1:]·b[0], solved for the 2×2 companion matrix; its pivot
    # 1 + a1 + a2 is 4ωn²/a0 exactly (summed, it cancels for a slow resonance)
    rhs = b[1:] - a[1:] * b[0]
    z0 = (rhs[0] + rhs[1]) / (4.0 * wn2 / a0)
    return b, a, np.array([z0, rhs[1] - a[2] * z0])


def _steady_lowpass(x: np.ndarray, filt: tuple[np.ndarray, np.ndarray, np.ndarray]) -> np.ndarray:
    """``aatest.twin.sensor.lowpass`` with its initial conditions computed once per filter."""
    b, a, zi = filt
    return signal.lfilter(b, a, x, zi=zi * x[0])[0]


def _logger(x: np.ndarray, info: ChannelInfo, dt_s: float) -> np.ndarray:
    """The logger's pre-sample filter (part of the nominal chain when the rig has one)."""
    if info.antialias_hz is None:
        return x
    return _steady_lowpass(x, _aa(float(info.antialias_hz), round(dt_s, 15)))


def _dynamics(x: np.ndarray, spec: Spec, dt_s: float) -> np.ndarray:
    if spec.dynamics is None:
        return x
    return _steady_lowpass(x, _dyn(float(spec.dynamics[0]), float(spec.dynamics[1]),
                                   round(dt_s, 15)))


#: the amplitude's band (Hz) and floor (°/s²) of ``amplitude_damping`` (see step_damped)
AMPLITUDE_BAND_HZ = 15.0
MIN_AMPLITUDE_DPS2 = 1.0


def step_amplitude_dps2(sr: StepReplay, info: ChannelInfo) -> float:
    """Amplitude A (√2·RMS, °/s²) of the step's motion along the sensor axis, within the
    15 Hz excitation band of ``amplitude_damping`` (memoised on the step).

    The twin reads A over a trailing 2.5 s window; over a steady sine step that window holds
    the same amplitude throughout, so one value per step is the twin's ζ(t) once the window
    has filled (the record's first samples aside).
    """
    key = ("amplitude", info.axis, AMPLITUDE_BAND_HZ)
    if key not in sr.memo:
        alpha = sensor_acceleration(sr, info.axis, sr.padded_time_s)[2]
        b, a = band_filter(AMPLITUDE_BAND_HZ, round(sr.dt_s, 15))
        band = signal.lfilter(b, a, alpha, zi=signal.lfilter_zi(b, a) * alpha[0])[0]
        sr.memo[key] = float(np.sqrt(2.0 * np.mean(band[PAD_SAMPLES:PAD_SAMPLES + sr.n] ** 2)))
    return float(sr.memo[key])


def step_damped(sr: StepReplay, info: ChannelInfo, spec: Spec) -> Spec:
    """``spec`` with ``amplitude_damping`` resolved for one step: the dynamics' damping at
    the step's amplitude, ζ(A) = ζ + c·log10(A/A_ref) within the twin's bounds.

    A step with less than :data:`MIN_AMPLITUDE_DPS2` along the sensor axis (an outer-axis
    sine seen through the cross-axis terms) is damped as at that floor: the twin's A there
    is set by cross-axis coefficients not known before the fit, and its response is that
    small part only.
    """
    if spec.amplitude_damping is None or spec.dynamics is None or not sr.dynamic:
        return spec
    c, ref = spec.amplitude_damping
    amp = max(step_amplitude_dps2(sr, info), MIN_AMPLITUDE_DPS2)
    zeta = damping_of(AmplitudeDamping(damping_per_decade=c, reference_dps2=ref),
                      spec.dynamics[1], np.array([amp]))
    return replace(spec, dynamics=(spec.dynamics[0], round(float(zeta[0]), 9)),
                   amplitude_damping=None)


def _ripple_columns(sr: StepReplay, t_eval: np.ndarray, n_cpd: float
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Inner-axis acceleration of a unit position ripple sin/cos(2π·n·θ) (°/s² per °)."""
    if not sr.inner.moving:
        zero = np.zeros_like(t_eval)
        return zero, zero
    _, _, acc_s, acc_c = ripple_regressors(sr, t_eval, n_cpd)
    return acc_s, acc_c


def _eval_times(sr: StepReplay, spec: Spec) -> tuple[np.ndarray, tuple[float, float, float]]:
    """Times (padded grid) at which the motion is evaluated, and their memo key."""
    shift = spec.shift_of(sr.index)
    t_ref = 0.0 if spec.warp_from_start else 0.5 * sr.time_s[-1]
    return _eval_times_of(sr.padded_time_s, sr, spec), (shift, spec.warp_ppm, t_ref)


def _eval_times_of(tp: np.ndarray, sr: StepReplay, spec: Spec) -> np.ndarray:
    """Evaluation times of the padded grid times ``tp`` under ``spec``'s shift and warp."""
    shift = spec.shift_of(sr.index)
    if spec.warp_ppm == 0.0:  # the same times (x − 0 is x), two passes fewer
        return tp - shift
    t_ref = 0.0 if spec.warp_from_start else 0.5 * sr.time_s[-1]
    return tp - shift - spec.warp_ppm * 1e-6 * (tp - t_ref)


#: design columns built on the sensed acceleration (computed by :func:`_sensor_columns`)
_SENSOR_COLUMNS = frozenset({"scale", "scale_temperature", "nonlinearity_cubic",
                             "jerk_sensitivity", "cross_x", "cross_y", "rotor_stiction",
                             "jerk_distortion"})


def _sensor_columns(sr: StepReplay, info: ChannelInfo, spec: Spec, t_eval: np.ndarray,
                    key: tuple, temp: np.ndarray, wanted: set[str]) -> dict[str, np.ndarray]:
    """The sensor chain: α → hysteresis → dynamics → saturation, and the ``wanted`` terms on it."""
    plugin_wanted = wanted.intersection(design_column_names(spec.linear))  # aatest.effects
    if not wanted & _SENSOR_COLUMNS and not plugin_wanted:
        return {}
    alpha3 = sensor_acceleration(sr, info.axis, t_eval, key)
    sensed = alpha3[2] + _ripple_motion(sr, info, spec, t_eval)
    if spec.hysteresis_dps2 > 0.0 and sr.dynamic:
        sensed = play_operator(sensed, spec.hysteresis_dps2)
    cols: dict[str, np.ndarray] = {}
    shaped = sensed
    if wanted & {"scale", "scale_temperature", "nonlinearity_cubic"} or plugin_wanted:
        shaped = _dynamics(sensed, spec, sr.dt_s)
        if spec.saturation_dps2 is not None:
            shaped = np.clip(shaped, -spec.saturation_dps2, spec.saturation_dps2)
        cols["scale"] = shaped
        if "scale_temperature" in wanted:
            cols["scale_temperature"] = shaped * temp
        if "nonlinearity_cubic" in wanted:
            cols["nonlinearity_cubic"] = shaped**3 / info.range_dps2**2
    if "jerk_sensitivity" in wanted:
        cols["jerk_sensitivity"] = np.gradient(sensed, sr.dt_s)
    if "rotor_stiction" in wanted:
        cols["rotor_stiction"] = _stiction_column(sr, info, spec, t_eval, sensed, key)
    if "jerk_distortion" in wanted:  # on the rotor's response, as the twin applies it
        cols["jerk_distortion"] = np.gradient(_dynamics(sensed, spec, sr.dt_s), sr.dt_s) ** 2
    if "cross_x" in wanted:
        cols["cross_x"] = _dynamics(alpha3[0], spec, sr.dt_s)
    if "cross_y" in wanted:
        cols["cross_y"] = _dynamics(alpha3[1], spec, sr.dt_s)
    if plugin_wanted:
        plugin_inputs = EffectInputs(shaped, sensed, temp, t_eval, sr.dt_s, info.range_dps2)
        cols |= design_columns(spec.linear, plugin_inputs,
                               {e: dict(v) for e, v in spec.plugin_shape})
    return cols


def _stiction_column(sr: StepReplay, info: ChannelInfo, spec: Spec, t_eval: np.ndarray,
                     sensed: np.ndarray, key: tuple) -> np.ndarray:
    """The response ``rotor_stiction`` removes (its coefficient is −depth·K): the sensed
    acceleration while the commanded rate about the sensor axis is within ±the break-away
    rate, through the dynamics (the twin's order: the gap acts before them)."""
    if spec.stiction_dps <= 0.0 or not sr.dynamic:
        return np.zeros_like(sensed)
    gap = _abs_rate(sr, info.axis, t_eval, key) < spec.stiction_dps
    return _dynamics(np.where(gap, sensed, 0.0), spec, sr.dt_s)


#: |commanded rate| evaluations kept per step (a break-away search meets one time grid only)
RATE_MEMO = 2


def _abs_rate(sr: StepReplay, axis: str, t_eval: np.ndarray, key: tuple) -> np.ndarray:
    """|commanded rate| about the sensor axis on the grid ``t_eval`` (memo key ``key``, the
    :data:`RATE_MEMO` most recently used kept): the break-away search tries a dozen and more
    gaps on one grid, and the rate (both axes' motion, the kinematics) is most of a column."""
    memo_key = ("abs rate", axis, key)
    value = sr.memo.pop(memo_key, None)
    if value is None:
        value = np.abs(sensor_rate(sr, axis, t_eval))
        held = [k for k in sr.memo if k[0] == "abs rate"]
        for old in held[: max(len(held) - RATE_MEMO + 1, 0)]:
            del sr.memo[old]
    sr.memo[memo_key] = value  # most recently used last
    return value


def _ripple_motion(sr: StepReplay, info: ChannelInfo, spec: Spec, t_eval: np.ndarray
                   ) -> np.ndarray | float:
    """Acceleration along the sensor axis of the ripple the table log shows (°/s²; 0 if none).

    Linear terms are unchanged by it (the ripple columns span it), nonlinear ones are not:
    a 2 cycles/° ripple at 60 °/s is a 120 Hz acceleration of hundreds of °/s², and the
    sensing element's cubic, clipping and backlash act on the sum of it and the command.
    """
    if not spec.ripple_motion_deg or not sr.inner.moving:
        return 0.0
    z_inner = float(E_I @ sensor_axes(info.axis, sr.pivoted)[:, 2])
    total = np.zeros_like(t_eval)
    for n_cpd, a_sin, a_cos in spec.ripple_motion_deg:
        acc_s, acc_c = _ripple_columns(sr, t_eval, n_cpd)
        total += a_sin * acc_s + a_cos * acc_c
    return z_inner * total


def _chain(dynamics: tuple[float, float] | None, antialias_hz: float | None, dt_s: float
           ) -> list[tuple[np.ndarray, np.ndarray]]:
    """(b, a) of the sensor's dynamics and the logger's filter, as the design applies them."""
    out = []
    if dynamics is not None:
        out.append(_dyn(float(dynamics[0]), float(dynamics[1]), round(dt_s, 15))[:2])
    if antialias_hz is not None:
        out.append(_aa(float(antialias_hz), round(dt_s, 15))[:2])
    return out


@lru_cache(maxsize=4096)
def _chain_response(dynamics: tuple[float, float] | None, antialias_hz: float | None,
                    dt_s: float, omega_rad: float) -> complex | None:
    """:func:`~aatest.diagnose.steady_state.response` of :func:`_chain` at Ω rad/sample,
    memoised: every tone column of every step is rebuilt on each shape a search tries, most
    of them under a chain and at a frequency met before (a few numbers per entry)."""
    return response(_chain(dynamics, antialias_hz, dt_s), omega_rad, PAD_SAMPLES)


def _tones(sr: StepReplay, info: ChannelInfo, spec: Spec, t_eval: np.ndarray,
           wanted: set[str], z_inner: float) -> tuple[dict[str, np.ndarray], list[int]]:
    """Vibration columns on the record grid, through dynamics and logger, evaluated in the
    frequency domain (:mod:`aatest.diagnose.steady_state`); and the tones left to the time
    domain (a filter that rings beyond the padding)."""
    done: dict[str, np.ndarray] = {}
    left: list[int] = []
    step_s = float(t_eval[1] - t_eval[0])
    t_ref = tone_reference_s(sr, spec)
    for j, f_hz in enumerate(spec.vibration_hz if sr.motor_on else ()):
        names = (f"vib{sr.index}_{j}_s", f"vib{sr.index}_{j}_c")
        if wanted.isdisjoint(names):
            continue
        gain = tone_gain(sr, info, spec, f_hz, step_s)
        if gain is None:
            left.append(j)
            continue
        basis = _tone_basis(sr, f_hz, spec.warp_ppm, t_ref)
        done[names[0]], done[names[1]] = tone_columns(gain, basis, z_inner)
    return done, left


def tone_reference_s(sr: StepReplay, spec: Spec) -> float:
    """Time (s in the record) about which the clock warp turns the tones."""
    return 0.0 if spec.warp_from_start else 0.5 * sr.time_s[-1]


def eval_step_s(sr: StepReplay, spec: Spec) -> float:
    """Spacing of the evaluation grid of :func:`_eval_times` (its first two samples, with
    the same arithmetic), without evaluating the whole grid."""
    return float(np.diff(_eval_times_of(sr.padded_time_s[:2], sr, spec))[0])


def tone_gain(sr: StepReplay, info: ChannelInfo, spec: Spec, f_hz: float,
              step_s: float | None = None) -> complex | None:
    """Complex gain of one vibration tone through dynamics and logger (``spec`` resolved for
    the step, :func:`step_damped`), with the step's time shift turning its phase; None when
    a filter rings beyond the padding (the tone is then filtered in the time domain).

    The tone's design columns are Re and Im of gain·e^{iθ} with θ = 2πf·t (warped, not
    shifted): ``gain.real·sin θ + gain.imag·cos θ`` and ``gain.real·cos θ − gain.imag·sin θ``
    (:func:`~aatest.diagnose.steady_state.tone_columns`), so everything a delay or the
    dynamics change about a tone is in this one number.
    """
    w = 2 * np.pi * f_hz
    step = eval_step_s(sr, spec) if step_s is None else step_s
    h = _chain_response(spec.dynamics, info.antialias_hz, sr.dt_s, w * step)
    if h is None:
        return None
    # a time shift turns the tone's phase: it goes into the complex gain, and the sine and
    # cosine of the unshifted tone are computed once per warp
    return complex(h * np.exp(-1j * w * spec.shift_of(sr.index)))


def inner_projection(sr: StepReplay, info: ChannelInfo) -> float:
    """Share of an inner-axis acceleration along the sensor's sensitive axis."""
    return float(E_I @ sensor_axes(info.axis, sr.pivoted)[:, 2])


def tone_basis_row(sr: StepReplay, f_hz: float, warp_ppm: float, from_start: bool,
                   part: str) -> np.ndarray:
    """sin θ (``part`` "s") or cos θ ("c") of one tone on the record grid (read-only)."""
    t_ref = 0.0 if from_start else 0.5 * sr.time_s[-1]
    sin, cos = _tone_basis(sr, f_hz, warp_ppm, t_ref)
    return sin if part == "s" else cos


def _tone_basis(sr: StepReplay, f_hz: float, warp_ppm: float, t_ref: float
                ) -> tuple[np.ndarray, np.ndarray]:
    """sin and cos of 2πf·t on the record grid, t warped about ``t_ref`` and not shifted
    (the :data:`TONE_MEMO` most recently used kept on the step)."""
    key = ("tone", f_hz, warp_ppm, t_ref)
    value = sr.memo.pop(key, None)
    if value is None:
        t = sr.time_s
        theta = 2 * np.pi * f_hz * (t - warp_ppm * 1e-6 * (t - t_ref))
        value = (np.sin(theta), np.cos(theta))
        tones = [k for k in sr.memo if k[0] == "tone"]
        for old in tones[: max(len(tones) - TONE_MEMO + 1, 0)]:
            del sr.memo[old]
    sr.memo[key] = value  # most recently used last
    return value


def _table_columns(sr: StepReplay, info: ChannelInfo, spec: Spec,
                   t_eval: np.ndarray, wanted: set[str], tones: list[int] | None = None
                   ) -> dict[str, np.ndarray]:
    """Inner-axis ripple and vibration as seen along the sensor axis, through its dynamics
    (vibration: only the tones ``tones``, every one when None)."""
    z_inner = float(E_I @ sensor_axes(info.axis, sr.pivoted)[:, 2])
    cols: dict[str, np.ndarray] = {}
    for n in spec.ripple_cpd:
        rnames = (f"ripple{n:g}_s", f"ripple{n:g}_c")
        if wanted.isdisjoint(rnames):
            continue
        rs, rc = _ripple_columns(sr, t_eval, n)
        cols[rnames[0]] = _dynamics(z_inner * rs, spec, sr.dt_s)
        cols[rnames[1]] = _dynamics(z_inner * rc, spec, sr.dt_s)
    for j, f_hz in enumerate(spec.vibration_hz if sr.motor_on else ()):
        names = (f"vib{sr.index}_{j}_s", f"vib{sr.index}_{j}_c")
        if wanted.isdisjoint(names) or (tones is not None and j not in tones):
            continue
        w = 2 * np.pi * f_hz
        cols[names[0]] = _dynamics(z_inner * np.sin(w * t_eval), spec, sr.dt_s)
        cols[names[1]] = _dynamics(z_inner * np.cos(w * t_eval), spec, sr.dt_s)
    return cols


def _design(sr: StepReplay, info: ChannelInfo, spec: Spec, wanted: set[str]
            ) -> dict[str, np.ndarray]:
    """The ``wanted`` design columns of one step on its record grid, by name (volts per unit
    coefficient); a name absent from the result is zero on this step (another step's
    vibration term, a term of an effect this step cannot excite)."""
    cut = slice(PAD_SAMPLES, PAD_SAMPLES + sr.n)
    out: dict[str, np.ndarray] = {}
    if "bias" in wanted:
        out["bias"] = np.ones(sr.n)
    dynamic = wanted - {"bias", "bias_temperature", "g_sensitivity"}
    temp: np.ndarray | None = None
    if dynamic or "bias_temperature" in wanted:
        temp = _temperature(sr, info, sr.n + 2 * PAD_SAMPLES)
    if dynamic:
        assert temp is not None
        t_eval, key = _eval_times(sr, spec)
        spec = step_damped(sr, info, spec)
        z_inner = float(E_I @ sensor_axes(info.axis, sr.pivoted)[:, 2])
        done, left = _tones(sr, info, spec, t_eval, dynamic, z_inner)
        cols = (_sensor_columns(sr, info, spec, t_eval, key, temp, dynamic)
                | _table_columns(sr, info, spec, t_eval, dynamic, left))
        out |= {name: _logger(col, info, sr.dt_s)[cut] for name, col in cols.items()
                if name in dynamic}
        out |= {name: col for name, col in done.items() if name in dynamic}
    if "bias_temperature" in wanted:
        assert temp is not None
        out["bias_temperature"] = temp[cut]
    if "g_sensitivity" in wanted:
        out["g_sensitivity"] = gravity_along(sr, info.axis)
    return out


def step_columns(sr: StepReplay, info: ChannelInfo, spec: Spec, names: list[str],
                 used_out: list[int] | None = None) -> np.ndarray:
    """Design columns of one step on its record grid, shape (n, len(names)).

    Dynamic columns pass through the logger filter; ``used_out``, when given, receives the
    indices of the columns this step can make non-zero (others, e.g. another step's
    vibration terms, are zero by construction).
    """
    cols = _design(sr, info, spec, set(names))
    out = np.zeros((len(names), sr.n))  # filled by rows (contiguous), returned transposed
    used = [j for j, name in enumerate(names) if name in cols]
    for j in used:
        out[j] = cols[names[j]]
    if used_out is not None:
        used_out.extend(used)
    return out.T


def _temperature(sr: StepReplay, info: ChannelInfo, padded: int) -> np.ndarray:
    """T − T_ref on the padded grid (edge values held), °C; read-only, memoised on the step
    (every column build of every spec needs it)."""
    key = ("temperature", info.t_ref_c, padded)
    value = sr.memo.get(key)
    if value is None:
        if sr.temperature_c is None:
            value = np.zeros(padded)
        else:
            value = np.pad(sr.temperature_c - info.t_ref_c, PAD_SAMPLES, mode="edge")
        value.flags.writeable = False
        sr.memo[key] = value
    return value


def _step_key(spec: Spec, sr: StepReplay) -> Spec:
    """The part of ``spec`` a step's columns depend on (a still step ignores the shape)."""
    spec = replace(spec, delay_s=spec.shift_of(sr.index), step_shift_s=())
    if sr.dynamic:
        return spec
    key = replace(spec, hysteresis_dps2=0.0, saturation_dps2=None, stiction_dps=0.0)
    if not spec.ripple_cpd and not spec.vibration_hz:
        key = replace(key, delay_s=0.0, dynamics=None, warp_ppm=0.0, amplitude_damping=None)
    return key


def predict(replay: Replay, info: ChannelInfo, fit: Fit) -> dict[int, np.ndarray]:
    """Model output (volts) per step for a fitted spec.

    Only the columns a step can make non-zero are built (a model with vibration terms has
    two per tone per step, zero on every other step).
    """
    out = {}
    for sr in replay.steps:
        cols = _design(sr, info, fit.spec, set(fit.names))
        used = [j for j, name in enumerate(fit.names) if name in cols]
        x = np.stack([cols[fit.names[j]] for j in used])
        out[sr.index] = fit.coef[used] @ x
    return out
