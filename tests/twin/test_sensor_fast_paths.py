"""The sensor model's fast paths give the very numbers of their plain definitions.

Speed work on the twin must not move a recorded value (a last-bit change flips ADC codes), so
each rewritten stage is pinned bit for bit (``np.array_equal``) against the straightforward
formulation it replaced. Bit identity is the right tolerance here: both sides perform the same
IEEE operations on the same operands (selections, sums in the same order, a prefix of the
same recursion), only fewer of them or without temporaries.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from aatest.plugins.sensors.sr207 import SR207Unit
from aatest.twin import sensor as sn
from aatest.twin import zeta_blend as zb
from aatest.twin.api import realistic_rig_model
from aatest.twin.model import SensorModel

DT_S = 1.0 / 2000.0


def _sensor() -> SensorModel:
    """A datasheet channel with amplitude-dependent damping (the stepped sine's sensor)."""
    model = realistic_rig_model(SR207Unit().datasheet()).sensors[0]
    assert model.amplitude_damping is not None and model.sensor_dynamics is not None
    return model


def _swept_alpha(n: int, seed: int) -> np.ndarray:
    """Acceleration (°/s²) whose amplitude sweeps two decades, so ζ(t) crosses many grid
    filters, plus white noise and a 35 Hz tone."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * DT_S
    envelope = 10.0 ** np.interp(t, [0.0, t[-1]], [0.0, 2.0])
    return envelope * np.sin(2 * np.pi * 3.0 * t) + 0.5 * np.sin(2 * np.pi * 35.0 * t) \
        + rng.standard_normal(n)


def _reference_trailing(x: np.ndarray, window: int, state: sn.ChannelState | None) -> np.ndarray:
    """The plain definition: window sums by index arrays."""
    sq = np.asarray(x, dtype=np.float64) ** 2
    tail = state.filters.get("amplitude_tail") if state is not None else None
    full = sq if tail is None else np.concatenate([tail, sq])
    csum = np.concatenate([[0.0], np.cumsum(full)])
    end = np.arange(full.size - sq.size, full.size) + 1
    start = np.maximum(end - window, 0)
    if state is not None:
        state.filters["amplitude_tail"] = full[-max(window - 1, 1):]
    return np.sqrt(2.0 * (csum[end] - csum[start]) / (end - start))


def _reference_dynamics(model: SensorModel, alpha: np.ndarray,
                        state: sn.ChannelState | None) -> np.ndarray:
    """The plain definition: Σ_k w_k·y_k over every grid filter k, each run over the block."""
    dyn, eff = model.sensor_dynamics, model.amplitude_damping
    assert dyn is not None and eff is not None
    b, a = sn.band_filter(eff.band_hz, round(DT_S, 15))
    band = sn.lowpass_carry(alpha, b, a, "amplitude_band", state)
    amplitude = _reference_trailing(band, max(round(eff.window_s / DT_S), 1), state)
    grid = sn.damping_of(eff, dyn.damping, amplitude) / sn._ZETA_STEP
    low = np.floor(grid).astype(np.int64)
    frac = grid - low
    out = np.zeros_like(alpha, dtype=np.float64)
    used = set()
    for k in range(int(low.min()), int(low.max()) + 2):
        weight = np.where(low == k, 1.0 - frac, 0.0) + np.where(low == k - 1, frac, 0.0)
        if not weight.any():
            continue
        b, a = sn.dynamics_filter(dyn.natural_frequency_hz, round(k * sn._ZETA_STEP, 6),
                                  round(DT_S, 15))
        used.add(f"dynamics:{k}")
        out += weight * sn.lowpass_carry(alpha, b, a, f"dynamics:{k}", state)
    if state is not None:
        for key in [k for k in state.filters if k.startswith("dynamics:") and k not in used]:
            del state.filters[key]
    return out


@pytest.mark.parametrize("n", [1, 7, 4999, 5000, 5001, 40_000])
def test_trailing_amplitude_by_slices_equals_the_indexed_sums(n: int) -> None:
    x = _swept_alpha(max(n, 2), 3)[:n]
    assert np.array_equal(sn.trailing_amplitude(x, 5000, None), _reference_trailing(x, 5000, None))


def test_trailing_amplitude_continues_blocks_as_the_indexed_sums() -> None:
    x = _swept_alpha(23_000, 4)
    fast, ref = sn.ChannelState(), sn.ChannelState()
    for lo, hi in ((0, 3000), (3000, 3001), (3001, 11_000), (11_000, 23_000)):
        assert np.array_equal(sn.trailing_amplitude(x[lo:hi], 5000, fast),
                              _reference_trailing(x[lo:hi], 5000, ref))


@pytest.mark.parametrize("seed", [0, 1])
def test_amplitude_dynamics_of_a_whole_record_equals_the_weighted_sum(seed: int) -> None:
    model, alpha = _sensor(), _swept_alpha(30_000, seed)
    expected = _reference_dynamics(model, alpha, None)
    assert np.array_equal(sn.amplitude_dynamics(model, alpha, DT_S, None), expected)
    final = sn.ChannelState(final=True)  # filters stop at their last weighted sample
    assert np.array_equal(sn.amplitude_dynamics(model, alpha, DT_S, final), expected)


def test_amplitude_dynamics_block_by_block_equals_the_weighted_sum() -> None:
    """Filter states carry over as before; only the last block may stop its filters early."""
    model, alpha = _sensor(), _swept_alpha(36_000, 2)
    fast, ref = sn.ChannelState(), sn.ChannelState()
    bounds = ((0, 4000), (4000, 20_000), (20_000, 36_000))
    for lo, hi in bounds:
        fast.final = hi == bounds[-1][1]
        assert np.array_equal(sn.amplitude_dynamics(model, alpha[lo:hi], DT_S, fast),
                              _reference_dynamics(model, alpha[lo:hi], ref))
        assert sorted(fast.filters) == sorted(ref.filters)


@pytest.mark.parametrize("runs", ["few", "many"])
def test_blend_equals_the_ascending_weighted_sum_with_exact_zeros(runs: str) -> None:
    """frac = 0 (an unused upper filter), negative zeros, filters cut after their last
    weighted sample; few runs of one filter pair (slices) and many (one gather)."""
    rng = np.random.default_rng(5)
    n, k0 = 4000, 10
    if runs == "few":
        low = k0 + np.repeat(rng.integers(0, 4, 20), n // 20)
    else:
        low = k0 + rng.integers(0, 4, n)
    frac = rng.random(n)
    frac[::5] = 0.0
    frac[n // 2:n // 2 + 300] = 0.0
    rows = rng.standard_normal((6, n))
    rows[:, ::7] = -0.0
    _, needed = zb.filters_needed(low, frac)
    filtered = {r: rows[r, :needed[r] + 1] for r in np.flatnonzero(needed >= 0).tolist()}
    expected = np.zeros(n)
    for k in range(int(low.min()), int(low.max()) + 2):
        weight = np.where(low == k, 1.0 - frac, 0.0) + np.where(low == k - 1, frac, 0.0)
        if weight.any():
            expected += weight * rows[k - k0]
    got = zb.blend(filtered, low - k0, frac)
    assert np.array_equal(got, expected)
    assert np.array_equal(np.signbit(got), np.signbit(expected))


def _reference_drift(drift, n: int, state: sn.ChannelState) -> np.ndarray:
    """The plain definition of :func:`sensor.bias_drift_v` (new arrays at every step)."""
    rng = state.drift_rng
    t_s = state.elapsed_s + DT_S * np.arange(n)
    out = drift.rate_v_per_h * t_s / 3600.0
    steps = drift.random_walk_v_per_sqrt_s * np.sqrt(DT_S) * sn.standard_normal(rng, n)
    walk = state.walk_v + np.cumsum(steps)
    state.walk_v = float(walk[-1])
    out = out + walk
    phi = float(np.exp(-DT_S / drift.correlation_s))
    w = np.sqrt(1.0 - phi * phi) * drift.instability_v * sn.standard_normal(rng, n)
    markov, _ = signal.lfilter([1.0], [1.0, -phi], w, zi=[phi * state.markov_v])
    state.markov_v = float(markov[-1])
    state.elapsed_s += DT_S * n
    return out + markov


def test_bias_drift_in_place_equals_its_plain_definition() -> None:
    drift = _sensor().bias_drift
    assert drift is not None and drift.random_walk_v_per_sqrt_s > 0 and drift.instability_v > 0
    fast = sn.ChannelState(drift_rng=np.random.default_rng(8))
    ref = sn.ChannelState(drift_rng=np.random.default_rng(8))
    for n in (1, 5000, 30_001):
        expected = _reference_drift(drift, n, ref)
        assert np.array_equal(sn.bias_drift_v(drift, n, DT_S, fast), expected)


def test_filters_needed_are_the_nonzero_weights() -> None:
    low = np.array([5, 5, 6, 8, 8, 6, 5])
    frac = np.array([0.5, 0.0, 0.0, 0.25, 0.0, 0.0, 0.0])
    k0, last = zb.filters_needed(low, frac)
    # k = 5: samples 0, 1, 6; k = 6: 0 (5 + frac) and 2, 5; k = 7: none (frac 0 at 6);
    # k = 8: 3, 4; k = 9: 3 (8 + frac)
    assert k0 == 5
    assert last.tolist() == [6, 5, -1, 4, 3]


def test_play_operator_equals_its_recursion_bit_for_bit() -> None:
    x = _swept_alpha(20_000, 6)
    for r, y0 in ((0.05, None), (3.0, 1.0), (40.0, -7.0)):
        y, prev = np.empty_like(x), (x[0] if y0 is None else y0)
        for k, xk in enumerate(x.tolist()):
            prev = min(xk + r, max(xk - r, prev))
            y[k] = prev
        assert np.array_equal(sn.play_operator(x, r, y0), y)


def test_unit_steady_state_is_lfilter_zi() -> None:
    b, a = sn.dynamics_filter(30.0, 0.7, DT_S)
    assert np.array_equal(sn.unit_steady_state(b, a), signal.lfilter_zi(b, a))
    b4, a4 = sn.band_filter(15.0, DT_S)
    assert np.array_equal(sn.unit_steady_state(b4, a4), signal.lfilter_zi(b4, a4))
