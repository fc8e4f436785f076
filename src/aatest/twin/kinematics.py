"""Two-axis table kinematics: frames, sensor axes, angular acceleration and gravity.

Frames (docs/interfaces.md §4 "Frames"). Table-top coordinates are ordered (P, O, I) so that a
sensor on I with x along P and y along O is right-handed. The outer axis O is fixed in the lab and
horizontal; the inner axis I is carried by the outer gimbal and points up at outer 0°; the table
top turns about I by the inner angle ψ. Every vector below is expressed in the *table-top* frame,
which is the frame the sensors are bolted to.

Why kinematics and not special cases: the coordinated two-axis excitation
α = −ω_i·ω_o·sin(ω_i t) (docs/method.md §3) and the "outer motion seen along (sin ψ, cos ψ, 0)" rule
both fall out of differentiating the body-frame angular velocity
ω_top = ω_i·e_I + R_z(ψ)ᵀ·R_x(ε)ᵀ·ω_o·e_O, with ε the orthogonality error of the gimbal.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: table-top unit vectors (P, O, I) coordinates
E_P = np.array([1.0, 0.0, 0.0])
E_O = np.array([0.0, 1.0, 0.0])
E_I = np.array([0.0, 0.0, 1.0])

ARCSEC_RAD = np.pi / (180.0 * 3600.0)

#: sensor frames on the block, columns = sensor (x, y, z) in table-top coordinates;
#: each right-handed with z the sensitive axis (S_Z on I, S_Y on O, S_X on P).
SEAT_FRAMES: dict[str, np.ndarray] = {
    "I": np.column_stack([E_P, E_O, E_I]),
    "O": np.column_stack([E_I, E_P, E_O]),
    "P": np.column_stack([E_O, E_I, E_P]),
}


def rotation(axis: np.ndarray, angle_rad: float) -> np.ndarray:
    """Rotation matrix of ``angle_rad`` about the unit vector ``axis`` (Rodrigues)."""
    axis = np.asarray(axis, dtype=float)
    axis = axis / np.linalg.norm(axis)
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + np.sin(angle_rad) * k + (1.0 - np.cos(angle_rad)) * (k @ k)


def tilt(angle_deg: float, azimuth_deg: float) -> np.ndarray:
    """Small rotation that tilts a frame's z axis by ``angle_deg`` towards azimuth (0° = +x).

    Used for input-axis misalignment: z' = R·z leans towards x at azimuth 0°, towards y at 90°.
    """
    az = np.radians(azimuth_deg)
    # rotating about (−sin az, cos az, 0) by +angle tips z towards (cos az, sin az, 0)
    return rotation(np.array([-np.sin(az), np.cos(az), 0.0]), np.radians(angle_deg))


def random_small_rotation(rng: np.random.Generator, sigma_deg: float) -> np.ndarray:
    """A random rotation with independent N(0, σ²) angles about the three axes (degrees)."""
    if sigma_deg <= 0.0:
        return np.eye(3)
    angles = np.radians(rng.normal(0.0, sigma_deg, 3))
    return rotation(E_P, angles[0]) @ rotation(E_O, angles[1]) @ rotation(E_I, angles[2])


@dataclass(frozen=True)
class GimbalErrors:
    """Geometric errors of the gimbal (datasheet: wobble ≤ 2″, orthogonality ≤ 3″)."""

    orthogonality_arcsec: float = 0.0
    wobble_arcsec: float = 0.0


def angular_acceleration_top(
    inner_sincos: tuple[np.ndarray, np.ndarray],
    inner_rate_dps: np.ndarray,
    inner_accel_dps2: np.ndarray,
    outer_rate_dps: np.ndarray,
    outer_accel_dps2: np.ndarray,
    gimbal: GimbalErrors = GimbalErrors(),
) -> np.ndarray:
    """Angular acceleration of the table top in its own frame, shape (3, n), °/s².

    d/dt of the body-frame angular velocity; includes the Coriolis-like cross term
    ω_o·ω_i (in rad/s units, converted back to °/s²) that makes coordinated motion work.
    ``inner_sincos`` = (sin ψ, cos ψ) of the inner angle (see :func:`sincos_deg`).
    """
    s, c = inner_sincos
    eps = gimbal.orthogonality_arcsec * ARCSEC_RAD
    # outer axis in the inner-base frame: R_x(ε)ᵀ·e_O = (0, cos ε, −sin ε)
    v_o, v_i = np.cos(eps), -np.sin(eps)
    cross = np.radians(inner_rate_dps) * outer_rate_dps  # (rad/s)·(°/s) = °/s²
    alpha = np.empty((3, *np.shape(s)))
    rows = _rows(alpha)
    # each row formed in place in its output (a·b and a + b commute bit for bit)
    row = np.multiply(outer_accel_dps2, s, out=rows[0])  # v_o·(α_o·s + cross·c)
    scratch = np.multiply(cross, c, out=np.empty_like(rows[0]))
    row += scratch
    row *= v_o
    row = np.multiply(outer_accel_dps2, c, out=rows[1])  # v_o·(α_o·c − cross·s)
    row -= np.multiply(cross, s, out=scratch)
    row *= v_o
    row = np.multiply(outer_accel_dps2, v_i, out=rows[2])  # α_i + v_i·α_o
    row += inner_accel_dps2
    return _apply_wobble(alpha, s, c, gimbal.wobble_arcsec)


def angular_rate_top(inner_sincos: tuple[np.ndarray, np.ndarray], inner_rate_dps: np.ndarray,
                     outer_rate_dps: np.ndarray, gimbal: GimbalErrors = GimbalErrors()
                     ) -> np.ndarray:
    """Angular velocity of the table top in its own frame, shape (3, n), °/s.

    The quantity whose derivative :func:`angular_acceleration_top` is (the same outer-axis
    direction, orthogonality and wobble).
    """
    s, c = inner_sincos
    eps = gimbal.orthogonality_arcsec * ARCSEC_RAD
    v_o, v_i = np.cos(eps), -np.sin(eps)
    rate = np.empty((3, *np.shape(s)))
    rate[0] = v_o * outer_rate_dps * s
    rate[1] = v_o * outer_rate_dps * c
    rate[2] = inner_rate_dps + v_i * outer_rate_dps
    return _apply_wobble(rate, s, c, gimbal.wobble_arcsec)


def gravity_top(inner_sincos: tuple[np.ndarray, np.ndarray],
                outer_sincos: tuple[np.ndarray, np.ndarray],
                gimbal: GimbalErrors = GimbalErrors()) -> np.ndarray:
    """Specific force of a body at rest (the 'up' unit vector, in g) in the top frame, (3, n).

    +1 g along I at outer 0°, −1 g at outer 180° (docs/interfaces.md §4 "Gravity").
    """
    s, c = inner_sincos
    sin_phi, cos_phi = outer_sincos
    eps = gimbal.orthogonality_arcsec * ARCSEC_RAD
    # up in the outer frame is (−sin φ, 0, cos φ); then R_x(ε)ᵀ, then R_z(ψ)ᵀ
    u0 = -sin_phi
    u1 = np.sin(eps) * cos_phi
    up = np.empty((3, *np.shape(s)))
    rows = _rows(up)
    # c·u0 + s·u1 and −s·u0 + c·u1 = c·u1 − s·u0 ((−a)·b = −(a·b), x + (−y) = x − y and
    # a + b = b + a, bit for bit), each in its output row
    row = np.multiply(c, u0, out=rows[0])
    scratch = np.multiply(s, u1, out=np.empty_like(rows[0]))
    row += scratch
    row = np.multiply(c, u1, out=rows[1])
    row -= np.multiply(s, u0, out=scratch)
    np.multiply(np.cos(eps), cos_phi, out=rows[2])
    return _apply_wobble(up, s, c, gimbal.wobble_arcsec)


def _apply_wobble(vec: np.ndarray, s: np.ndarray, c: np.ndarray,
                  wobble_arcsec: float) -> np.ndarray:
    """Tilt by the wobble angle about a direction fixed in the inner-base frame (small angle).

    The bearing tilt is fixed relative to the outer gimbal, so the top sees it turn once per
    inner revolution: v' = v + w·(a × v) with a = R_z(ψ)ᵀ·e_P = (cos ψ, −sin ψ, 0).
    Updates ``vec`` in place (callers pass freshly built arrays) and returns it.
    """
    w = wobble_arcsec * ARCSEC_RAD
    if w == 0.0:
        return vec
    # with a = (c, −s): z += w·(c·y + s·x), x −= w·(s·z), y −= w·(c·z) — the operations of
    # a0·y − a1·x and x + w·(a1·z) with the signs folded ((−a)·b = −(a·b), x − (−y) = x + y)
    rows = _rows(vec)
    z = rows[2].copy()
    term = np.multiply(c, rows[1], out=np.empty_like(rows[1]))
    scratch = np.multiply(s, rows[0], out=np.empty_like(rows[0]))
    term += scratch
    term *= w
    rows[2] += term
    np.multiply(s, z, out=term)
    term *= w
    rows[0] -= term
    np.multiply(c, z, out=term)
    term *= w
    rows[1] -= term
    return vec


def lab_horizontal_top(inner_sincos: tuple[np.ndarray, np.ndarray],
                       outer_sincos: tuple[np.ndarray, np.ndarray],
                       about_lab: np.ndarray) -> np.ndarray:
    """Angular acceleration about the two horizontal lab axes, expressed in the top frame.

    ``about_lab`` (2, n): about the lab axis along P at outer 0° and about O (°/s²).
    R_y(φ)ᵀ·e_P = (cos φ, 0, sin φ) and e_O stay horizontal; R_z(ψ)ᵀ brings both to the top.
    """
    s, c = inner_sincos
    sin_phi, cos_phi = outer_sincos
    h1, h2 = about_lab
    out = np.empty((3, *np.shape(h1)))
    rows = _rows(out)
    row = np.multiply(c, cos_phi, out=rows[0])  # h1·(c·cos φ) + h2·s, in the output row
    row *= h1
    scratch = np.multiply(h2, s, out=np.empty_like(rows[0]))
    row += scratch
    row = np.multiply(s, cos_phi, out=rows[1])  # h2·c − h1·(s·cos φ)
    row *= h1
    np.subtract(np.multiply(h2, c, out=scratch), row, out=row)
    np.multiply(h1, sin_phi, out=rows[2])
    return out


def _rows(vectors: np.ndarray) -> np.ndarray:
    """The three rows of a (3, …) result as arrays to write into (a single vector's rows as
    length-1 views: its elements are scalars, which ``out=`` cannot take)."""
    return vectors.reshape(3, 1) if vectors.ndim == 1 else vectors
