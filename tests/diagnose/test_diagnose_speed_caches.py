"""The speed-ups of ``aatest diagnose`` change no number: caches and fast sums against the
direct computation (timings are measured in ``bench/diagnose.py``, never here).

* per-step Gram blocks grown column by column, started from the block of the shape before
  (columns kept under what they depend on) and partly released under a memory budget, give
  the per-fold XᵀX, Xᵀy, yᵀy of the full design built from scratch;
* the O(n)-memory Lomb–Scargle periodogram equals SciPy's, the factorised single-frequency DFT
  equals the direct sum;
* the commanded-acceleration memo stays short and returns what an uncached evaluation does;
* vibration tones read from the filters' frequency response equal the time-domain filtering.
"""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy import signal

from aatest.diagnose import column_store, design
from aatest.diagnose.column_store import gram
from aatest.diagnose.design import step_columns
from aatest.diagnose.gram import fit_gram, fold_of
from aatest.diagnose.periodogram import dft_at, lomb_scargle_power
from aatest.diagnose.replay import ALPHA_MEMO, replay_dataset, sensor_acceleration
from aatest.diagnose.scenarios import draw_hidden, scenario_dataset
from aatest.diagnose.spec import ChannelInfo, Spec

INFO = ChannelInfo("v_sz", "I", 572.958, 100.0, 25.0)


@pytest.fixture(scope="module")
def replay():
    """Twelve steps (static, sines at several temperatures, outer-axis sines, ramps) of 2^12."""
    hidden = [draw_hidden("sensor_dynamics", 3), draw_hidden("bias_temperature", 3)]
    return replay_dataset(scenario_dataset(hidden, seed=3, samples=2**12))


def _targets(replay) -> dict[int, np.ndarray]:
    return {s.index: s.volts["v_sz"] for s in replay.steps}


def _direct(replay, spec: Spec) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per-fold XᵀX, Xᵀy, yᵀy, counts from each step's full design matrix (no cache)."""
    names = design.column_names(spec, replay)
    p = len(names)
    xtx, xty, yty, cnt = np.zeros((2, p, p)), np.zeros((2, p)), np.zeros(2), np.zeros(2)
    for sr in replay.steps:
        x, y, folds = step_columns(sr, INFO, spec, names), sr.volts["v_sz"], fold_of(sr.n)
        for f in (0, 1):
            m = folds == f
            xtx[f] += x[m].T @ x[m]
            xty[f] += x[m].T @ y[m]
            yty[f] += y[m] @ y[m]
            cnt[f] += m.sum()
    return xtx, xty, yty, cnt


#: specs in the order a diagnosis meets them: linear extensions of one shape, shape changes,
#: table terms, then back to earlier shapes (their blocks are re-used or rebuilt)
SPECS = [
    Spec(),
    Spec(linear=frozenset({"bias_temperature"})),
    Spec(linear=frozenset({"bias_temperature", "scale_temperature", "cross_axis"})),
    Spec(linear=frozenset({"nonlinearity_cubic", "jerk_sensitivity", "g_sensitivity"})),
    Spec(delay_s=0.0031),
    Spec(linear=frozenset({"bias_temperature"}), dynamics=(31.0, 0.6)),
    Spec(linear=frozenset({"bias_temperature", "scale_temperature"}), dynamics=(31.0, 0.6)),
    Spec(hysteresis_dps2=2.0, saturation_dps2=300.0),
    # the same dynamics with the damping following the amplitude, then differently: every
    # column through the dynamics changes although ``dynamics`` does not
    Spec(dynamics=(31.0, 0.6), amplitude_damping=(0.3, 10.0)),
    Spec(dynamics=(31.0, 0.6), amplitude_damping=(0.05, 10.0)),
    Spec(ripple_cpd=(2.0,), vibration_hz=(33.3,)),
    Spec(linear=frozenset({"cross_axis"}), ripple_cpd=(2.0,), vibration_hz=(33.3,),
         dynamics=(31.0, 0.6)),
    # vibration tones kept as sines and cosines, turned by a gain a delay and the dynamics set
    Spec(vibration_hz=(33.3, 47.11), dynamics=(31.0, 0.6), delay_s=0.0031),
    Spec(vibration_hz=(33.3, 47.11), dynamics=(29.0, 0.7), delay_s=0.0011),
    Spec(vibration_hz=(33.3, 47.11), dynamics=(29.0, 0.7), amplitude_damping=(0.2, 10.0)),
    Spec(),
    Spec(linear=frozenset({"bias_temperature", "scale_temperature", "cross_axis"})),
]


def _assert_same(g, direct) -> None:
    """Equal up to the summation order: every entry is a fold's dot product of N samples,
    summed here over one design and there over cached blocks (and by whichever BLAS kernel
    the CPU has), so |error| ≤ gamma_N·Σ|x_i·y_i| ≤ gamma_N·‖x‖·‖y‖ with gamma_N ≤ N·ε
    (Higham, Accuracy and Stability, §3.1; N = 24 576 per fold here: ≈ 5e-12 relative to
    ‖x‖·‖y‖)."""
    xtx, xty, yty, cnt = direct
    gamma = cnt.max() * np.finfo(float).eps
    norm = np.sqrt(np.diagonal(xtx, axis1=1, axis2=2))  # ‖x_j‖ per fold, (2, p)
    norm_y = np.sqrt(yty)
    assert np.all(np.abs(g.xtx - xtx) <= gamma * norm[:, :, None] * norm[:, None, :])
    assert np.all(np.abs(g.xty - xty) <= gamma * norm * norm_y[:, None])
    assert np.all(np.abs(g.yty - yty) <= gamma * yty)  # a sum of squares: condition 1
    assert_allclose(g.count, cnt, rtol=0)


def test_cached_gram_blocks_equal_the_full_design(replay) -> None:
    """One shared cache across every spec (as a Context uses it) changes no Gram entry."""
    cache: dict = {}
    targets = _targets(replay)
    for spec in SPECS:
        _assert_same(gram(replay, INFO, spec, targets, cache), _direct(replay, spec))


def test_released_columns_are_rebuilt_identically(replay, monkeypatch) -> None:
    """A budget too small to hold any column forces every extension to rebuild: same numbers."""
    monkeypatch.setattr(column_store, "COLUMN_BUDGET_BYTES", 1)
    cache: dict = {}
    targets = _targets(replay)
    for spec in SPECS:
        _assert_same(gram(replay, INFO, spec, targets, cache), _direct(replay, spec))
    assert len(cache[column_store.BUDGET_KEY].order) <= 1  # only the column just built is kept


@pytest.mark.pinned
def test_fit_with_and_without_cache_agree(replay) -> None:
    """The coefficients and held-out SSE a candidate is judged on do not depend on the cache."""
    targets = _targets(replay)
    cache: dict = {}
    for spec in SPECS[:3]:
        gram(replay, INFO, spec, targets, cache)  # warm the cache with the smaller specs
    spec = Spec(linear=frozenset({"bias_temperature", "scale_temperature"}), dynamics=(31.0, 0.6))
    cached = fit_gram(gram(replay, INFO, spec, targets, cache), spec)
    fresh = fit_gram(gram(replay, INFO, spec, targets, None), spec)
    assert_allclose(cached.coef, fresh.coef, rtol=1e-9)
    assert_allclose(cached.sse_held_out, fresh.sse_held_out, rtol=1e-9)
    # the data hold bias_temperature: its coefficient is the twin's drawn truth (V/°C)
    truth = draw_hidden("bias_temperature", 3).parameters["coefficient_v_per_c"]
    assert_allclose(cached.value("bias_temperature"), truth, rtol=0.05)


@pytest.mark.pinned
def test_lomb_scargle_power_equals_scipy() -> None:
    rng = np.random.default_rng(5)
    theta = np.sort(rng.uniform(-40.0, 40.0, 3000))
    y = 0.3 * np.sin(2 * np.pi * 1.37 * theta + 0.4) + rng.normal(size=theta.size)
    omega = 2 * np.pi * np.arange(0.2, 6.0, 0.01)  # evenly spaced: swept by rotation
    expected = signal.lombscargle(theta, y - y.mean(), omega)
    got = lomb_scargle_power(theta, y - y.mean(), omega)
    assert_allclose(got, expected, rtol=1e-9, atol=1e-10 * expected.max())
    assert abs(omega[np.argmax(got)] / (2 * np.pi) - 1.37) < 0.01
    uneven = np.sort(rng.uniform(1.0, 30.0, 7))  # not evenly spaced: exact phasors each time
    assert_allclose(lomb_scargle_power(theta, y, uneven), signal.lombscargle(theta, y, uneven),
                    rtol=1e-9)


@pytest.mark.parametrize("n", [16, 1000, 16384, 16387])
def test_dft_at_equals_the_direct_sum(n: int) -> None:
    rng = np.random.default_rng(n)
    values = rng.normal(size=n)
    t = 0.25 + 0.0005 * np.arange(n)
    for f_hz in (0.0, 3.3, 49.999, 999.0):
        direct = values @ np.exp(-2j * np.pi * f_hz * t)
        assert abs(dft_at(values, t, f_hz) - direct) <= 1e-11 * np.sqrt(n) * (1 + f_hz * t[-1])
    jittered = t + rng.normal(scale=1e-6, size=n)  # not uniform: the direct sum is used
    direct = values @ np.exp(-2j * np.pi * 3.3 * jittered)
    assert abs(dft_at(values, jittered, 3.3) - direct) <= 1e-9


def test_acceleration_memo_is_short_and_exact(replay) -> None:
    sr = next(s for s in replay.steps if s.dynamic)
    tp = sr.padded_time_s
    for k in range(3 * ALPHA_MEMO):
        shift = 1e-4 * k
        cached = sensor_acceleration(sr, "I", tp - shift, ("test", shift))
        assert_allclose(cached, sensor_acceleration(sr, "I", tp - shift), rtol=0, atol=0)
    assert sum(1 for key in sr.memo if key[0] == "alpha") <= ALPHA_MEMO
    again = sensor_acceleration(sr, "I", tp - 1e-4 * (3 * ALPHA_MEMO - 1),
                                ("test", 1e-4 * (3 * ALPHA_MEMO - 1)))
    assert_allclose(again, sensor_acceleration(sr, "I", tp - 1e-4 * (3 * ALPHA_MEMO - 1)))


@pytest.mark.parametrize("dynamics", [None, (31.0, 0.6), (2.0, 0.05)])
def test_vibration_columns_in_the_frequency_domain_equal_the_filtered_tone(replay, dynamics
                                                                           ) -> None:
    """A tone through the dynamics and the logger filter, read from their frequency response,
    equals the time-domain filtering on the padded grid (the padding settles both filters; a
    2 Hz resonance at ζ = 0.05 rings beyond it and keeps the time-domain path)."""
    spec = Spec(vibration_hz=(33.3, 47.11), dynamics=dynamics, delay_s=0.0031, warp_ppm=40.0)
    sr = next(s for s in replay.steps if s.motor_on)
    names = [f"vib{sr.index}_{j}_{p}" for j in range(2) for p in "sc"]
    got = design._design(sr, INFO, spec, set(names))
    t_eval, _ = design._eval_times(sr, spec)
    z = float(design.E_I @ design.sensor_axes(INFO.axis, sr.pivoted)[:, 2])
    cut = slice(design.PAD_SAMPLES, design.PAD_SAMPLES + sr.n)
    for j, f_hz in enumerate(spec.vibration_hz):
        for p, fn in (("s", np.sin), ("c", np.cos)):
            tone = z * fn(2 * np.pi * f_hz * t_eval)
            direct = design._logger(design._dynamics(tone, spec, sr.dt_s), INFO, sr.dt_s)[cut]
            # rounding of two recursive filters over 2^12 + 2048 samples: 1e-9 of the amplitude
            assert_allclose(got[f"vib{sr.index}_{j}_{p}"], direct, rtol=0,
                            atol=1e-9 * np.abs(direct).max())


@pytest.mark.parametrize(("natural_hz", "damping"), [(38.877, 0.653), (0.5, 0.05), (1000.0, 3.0)])
def test_closed_form_dynamics_filter_is_the_twins(natural_hz: float, damping: float) -> None:
    """The design's second-order filter in closed form is the twin's bilinear transform, and
    its initial state is the steady state of a unit input."""
    from aatest.twin.sensor import dynamics_filter

    dt_s = 0.0005
    b, a, zi = design._dyn(natural_hz, damping, dt_s)
    b_twin, a_twin = dynamics_filter(natural_hz, damping, dt_s)
    eps = np.finfo(np.float64).eps
    # sums of like-signed terms of size k² = (2/dt)², normalised by a0: a few operations each
    # rounding once, no cancellation (measured ≤ 2 eps on these cases)
    assert_allclose(b, b_twin, rtol=16 * eps)
    assert_allclose(a, a_twin, rtol=0, atol=16 * eps * np.abs(a_twin).max())
    _, zf = signal.lfilter(b, a, np.ones(20000), zi=zi)
    # a steady state stays put under a unit input, to the rounding of one step amplified by
    # the recursion's noise gain 1/(1 − |pole|): ≈ 13 at 38.9 Hz, ≈ 1.3e4 for the slow
    # resonance (0.5 Hz, ζ 0.05), where another CPU's rounding may legitimately reach ~1e-12
    noise_gain = 1.0 / (1.0 - np.abs(np.roots(a)).max())
    assert_allclose(zf, zi, rtol=8 * eps * noise_gain)
    # SciPy's lfilter_zi solves the same system (less accurately for a slow resonance:
    # its pivot 1 + a1 + a2 = 4ωn²/a0 is a difference of numbers near 1)
    assert_allclose(zi, signal.lfilter_zi(b_twin, a_twin), rtol=1e-9)


def test_still_outer_axis_acceleration_is_the_full_kinematics(replay) -> None:
    """With the outer axis still, the inner axis's acceleration alone is the top's: the same
    numbers as the full kinematics (every other term is an exact zero)."""
    from aatest.diagnose.replay import _sincos, kin, sensor_axes

    still = [sr for sr in replay.steps if not sr.outer.moving]
    assert still and len(still) < len(replay.steps)  # both paths are met by this replay
    for sr in replay.steps:
        t = sr.padded_time_s - 0.0013
        m = sr.motion(t)
        top = kin.angular_acceleration_top(_sincos(m["inner_angle"]), m["inner_rate"],
                                           m["inner_accel"], m["outer_rate"], m["outer_accel"])
        assert_allclose(sensor_acceleration(sr, "I", t), sensor_axes("I", sr.pivoted).T @ top,
                        rtol=0, atol=0)
