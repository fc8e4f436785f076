"""A pure tone through linear filters, evaluated in the frequency domain.

A vibration term of the design is a sine and a cosine at one frequency, passed through the
sensor's dynamics and the logger's pre-sample filter. Both are linear and time-invariant, so
once their start transient has died out the output is the same tone scaled and turned by the
filters' frequency response H(e^{iΩ}):

    sin θ_k → Re H·sin θ_k + Im H·cos θ_k,    cos θ_k → Re H·cos θ_k − Im H·sin θ_k

The design evaluates its columns on a grid padded by ``PAD_SAMPLES`` before the record starts
(:mod:`aatest.diagnose.replay`), so the time-domain filters start the record in steady state
whenever their slowest pole has decayed over the padding; then the two agree to rounding
(:data:`SETTLED`), and two sines replace two recursive filter passes over the padded grid per
tone and per shape (the joint polish of the sensor dynamics re-filters every tone of every
step on each of its ≈ 60 evaluations). A filter that rings longer than the padding (a
low, lightly damped resonance) is left to the time-domain path.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

#: a filter counts as settled when its slowest pole decays below this over the padding
SETTLED = 1e-13


@lru_cache(maxsize=256)
def _settles(a: tuple[float, ...], samples: int) -> bool:
    """Whether the all-pole part ``a`` decays below :data:`SETTLED` within ``samples``."""
    if len(a) < 2:  # noqa: PLR2004 - a pure FIR filter has no memory beyond its taps
        return True
    radius = float(np.max(np.abs(np.roots(a))))
    return radius < 1.0 and samples * np.log(radius) < np.log(SETTLED)


def response(filters: list[tuple[np.ndarray, np.ndarray]], omega_rad: float,
             settle_samples: int) -> complex | None:
    """H(e^{iΩ}) of the cascade ``filters`` ((b, a) each) at Ω rad/sample, or None when one
    of them has not settled within ``settle_samples``."""
    h = 1.0 + 0.0j
    z = np.exp(-1j * omega_rad)
    for b, a in filters:
        poles = np.atleast_1d(np.asarray(a, dtype=float))
        if not _settles(tuple(poles), settle_samples):
            return None
        h *= complex(np.polyval(np.asarray(b, dtype=float)[::-1], z)
                     / np.polyval(poles[::-1], z))
    return h


def tone_columns(h: complex, basis: tuple[np.ndarray, np.ndarray], gain: float
                 ) -> tuple[np.ndarray, np.ndarray]:
    """The steady-state outputs of ``gain``·sin θ and ``gain``·cos θ through response ``h``
    (``basis``: sin θ and cos θ). A delay τ of the input is the factor e^{−iωτ} in ``h``."""
    s, c = basis
    re, im = gain * h.real, gain * h.imag
    return re * s + im * c, re * c - im * s
