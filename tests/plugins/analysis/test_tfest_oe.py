"""Output-error (time-domain) transfer-function estimation: ``aatest.plugins.analysis.tfest_oe``."""

from __future__ import annotations

import numpy as np
import pytest

from aatest.plugins.analysis.tfest import DiscreteTf
from aatest.plugins.analysis.tfest_oe import fit_discrete_tf_oe, poly_to_rc, rc_to_poly

DT_S = 1.0 / 2000.0
#: a stable 2-pole/1-zero truth with a complex pole pair (|p| = 0.95)
NUM = np.array([0.02, 0.015])
DEN = np.poly([0.95 * np.exp(0.1j), 0.95 * np.exp(-0.1j)]).real


def _periodic_records(delay: int, seed: int = 3, n: int = 1024, count: int = 2
                      ) -> list[tuple[np.ndarray, np.ndarray]]:
    """Periodic white-noise inputs and the truth's exact steady-state (periodic) outputs."""
    rng = np.random.default_rng(seed)
    zinv = np.exp(-2j * np.pi * np.fft.rfftfreq(n))
    g = zinv**delay * np.polyval(NUM[::-1], zinv) / np.polyval(DEN[::-1], zinv)
    out = []
    for _ in range(count):
        u = rng.standard_normal(n)
        out.append((u, np.fft.irfft(g * np.fft.rfft(u), n)))
    return out


def test_reflection_coefficients_round_trip_a_stable_denominator() -> None:
    """Step-up after step-down returns the polynomial (a few roundings of O(1) numbers)."""
    a = np.poly([0.9, 0.5 + 0.3j, 0.5 - 0.3j, -0.2]).real
    k = poly_to_rc(a)
    assert np.all(np.abs(k) < 1.0)
    np.testing.assert_allclose(rc_to_poly(k), a, atol=1e-12)


@pytest.mark.parametrize("delay", [0, 5])
def test_recovers_the_truth_from_noise_free_periodic_records(delay: int) -> None:
    """Exact model class, no noise: the error surface's minimum is the truth; the least-squares
    search stops on its tolerances (1e-8 relative), so the coefficients agree to ~1e-5."""
    tf = fit_discrete_tf_oe(_periodic_records(delay), 2, 1, DT_S, delay)
    np.testing.assert_allclose(tf.den, DEN, atol=1e-5)
    np.testing.assert_allclose(tf.num, NUM, atol=1e-5)


def test_a_delay_longer_than_the_data_lag_stays_stable_and_costs_fit() -> None:
    """Forcing 8 samples on data that lag 0 needs lead the model can only mimic: the
    estimate stays stable (the parametrisation allows nothing else) and fits worse."""
    records = _periodic_records(0)
    exact = fit_discrete_tf_oe(records, 2, 1, DT_S, 0)
    late = fit_discrete_tf_oe(records, 2, 1, DT_S, 8)
    assert np.all(np.abs(late.poles()) < 1.0)
    assert _error(late, records) > 10 * _error(exact, records)


def test_a_stable_start_model_is_used_and_an_unstable_one_replaced() -> None:
    records = _periodic_records(0)
    unstable = DiscreteTf(num=np.array([0.1, 0.0]), den=np.array([1.0, -2.5, 1.2]),
                          delay_samples=0, dt=DT_S)
    tf = fit_discrete_tf_oe(records, 2, 1, DT_S, 0, start=unstable)
    np.testing.assert_allclose(tf.den, DEN, atol=1e-5)


def _error(tf: DiscreteTf, records: list[tuple[np.ndarray, np.ndarray]]) -> float:
    n = records[0][0].size
    zinv = np.exp(-2j * np.pi * np.fft.rfftfreq(n))
    g = tf.response(np.fft.rfftfreq(n, DT_S))
    assert np.allclose(zinv, np.exp(-2j * np.pi * np.fft.rfftfreq(n, DT_S) * DT_S))
    return float(sum(np.linalg.norm(np.fft.irfft(g * np.fft.rfft(u), n) - y) for u, y in records))
