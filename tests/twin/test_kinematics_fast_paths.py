"""The table-top kinematics formed in place give the numbers of their plain formulas, bit for bit.

Each row is now computed in its output array with the same IEEE operations on the same
operands (a·b and a + b commute; the wobble's and gravity's signs folded exactly:
(−a)·b = −(a·b) and x − (−y) = x + y), so equality is the check: a last-bit change would move
the recorded sensor volts.
"""

from __future__ import annotations

import numpy as np
import pytest

from aatest.twin import kinematics as kin
from aatest.twin.grid import sincos_deg

GIMBAL = kin.GimbalErrors(orthogonality_arcsec=3.0, wobble_arcsec=2.0)


def _wobble(vec: np.ndarray, s: np.ndarray, c: np.ndarray, wobble_arcsec: float) -> np.ndarray:
    w = wobble_arcsec * kin.ARCSEC_RAD
    if w == 0.0:
        return vec
    a0, a1 = c, -s
    z = vec[2].copy()
    vec[2] += w * (a0 * vec[1] - a1 * vec[0])
    vec[0] += w * (a1 * z)
    vec[1] -= w * (a0 * z)
    return vec


def _accel(sc: tuple[np.ndarray, np.ndarray], w_i: np.ndarray, a_i: np.ndarray,
           w_o: np.ndarray, a_o: np.ndarray, gimbal: kin.GimbalErrors) -> np.ndarray:
    s, c = sc
    eps = gimbal.orthogonality_arcsec * kin.ARCSEC_RAD
    v_o, v_i = np.cos(eps), -np.sin(eps)
    cross = np.radians(w_i) * w_o
    alpha = np.empty((3, *np.shape(s)))
    alpha[0] = v_o * (a_o * s + cross * c)
    alpha[1] = v_o * (a_o * c - cross * s)
    alpha[2] = a_i + v_i * a_o
    return _wobble(alpha, s, c, gimbal.wobble_arcsec)


def _gravity(sc: tuple[np.ndarray, np.ndarray], sc_o: tuple[np.ndarray, np.ndarray],
             gimbal: kin.GimbalErrors) -> np.ndarray:
    s, c = sc
    sin_phi, cos_phi = sc_o
    eps = gimbal.orthogonality_arcsec * kin.ARCSEC_RAD
    u0, u1, u2 = -sin_phi, np.sin(eps) * cos_phi, np.cos(eps) * cos_phi
    up = np.empty((3, *np.shape(s)))
    up[0] = c * u0 + s * u1
    up[1] = -s * u0 + c * u1
    up[2] = u2
    return _wobble(up, s, c, gimbal.wobble_arcsec)


def _horizontal(sc: tuple[np.ndarray, np.ndarray], sc_o: tuple[np.ndarray, np.ndarray],
                about_lab: np.ndarray) -> np.ndarray:
    s, c = sc
    sin_phi, cos_phi = sc_o
    h1, h2 = about_lab
    out = np.empty((3, *np.shape(h1)))
    out[0] = h1 * (c * cos_phi) + h2 * s
    out[1] = h2 * c - h1 * (s * cos_phi)
    out[2] = h1 * sin_phi
    return out


def _motion(n: int, seed: int) -> tuple[np.ndarray, ...]:
    """A coordinated two-axis motion with noise: inner and outer angle, rate, acceleration."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 2000.0
    th_i = 30.0 * t + 2.0 * np.sin(2 * np.pi * 3.0 * t) + 1e-3 * rng.standard_normal(n)
    th_o = 95.0 + 10.0 * t + 1e-3 * rng.standard_normal(n)
    return (th_i, 30.0 + rng.standard_normal(n), 500.0 * rng.standard_normal(n),
            th_o, 10.0 + rng.standard_normal(n), 50.0 * rng.standard_normal(n))


@pytest.mark.parametrize("gimbal", [GIMBAL, kin.GimbalErrors()])
@pytest.mark.parametrize("outer_moving", [True, False])
def test_top_kinematics_in_place_equal_the_plain_formulas(gimbal: kin.GimbalErrors,
                                                          outer_moving: bool) -> None:
    th_i, w_i, a_i, th_o, w_o, a_o = _motion(20_001, seed=11)
    sc_i = sincos_deg(th_i, True, 0.0)
    sc_o = sincos_deg(th_o, outer_moving, 95.0)
    assert np.array_equal(kin.angular_acceleration_top(sc_i, w_i, a_i, w_o, a_o, gimbal),
                          _accel(sc_i, w_i, a_i, w_o, a_o, gimbal))
    assert np.array_equal(kin.gravity_top(sc_i, sc_o, gimbal), _gravity(sc_i, sc_o, gimbal))
    floor = np.random.default_rng(12).standard_normal((2, th_i.size))
    assert np.array_equal(kin.lab_horizontal_top(sc_i, sc_o, floor),
                          _horizontal(sc_i, sc_o, floor))


def test_top_kinematics_of_one_instant_equal_the_plain_formulas() -> None:
    sc_i, sc_o = (np.sin(0.3), np.cos(0.3)), (np.sin(1.2), np.cos(1.2))
    assert np.array_equal(kin.angular_acceleration_top(sc_i, 20.0, 3.0, -7.0, 40.0, GIMBAL),
                          _accel(sc_i, 20.0, 3.0, -7.0, 40.0, GIMBAL))
    assert np.array_equal(kin.gravity_top(sc_i, sc_o, GIMBAL), _gravity(sc_i, sc_o, GIMBAL))
    floor = np.array([0.3, -0.2])
    assert np.array_equal(kin.lab_horizontal_top(sc_i, sc_o, floor),
                          _horizontal(sc_i, sc_o, floor))
