"""Discrete transfer-function estimation from frequency-response points (tfest-style).

Model (MATLAB's discrete ``tfest`` convention, ``dt`` = sample period T):

    H(z) = z^(−d) · (b0 + b1·z⁻¹ + … + bm·z⁻ᵐ) / (1 + a1·z⁻¹ + … + an·z⁻ⁿ),  m ≤ n.

At 2 kHz and ≤ 10 Hz every z = e^{jωT} lies within 0.03 rad of 1, so polynomials in z⁻¹ are
hopelessly ill-conditioned. The fit therefore runs in the scaled delta variable
w = (z − 1)/(ω₀T) (same polynomial spaces, well conditioned), by Sanathanan–Koerner iterations
and a Gauss–Newton output-error refinement (``scipy.optimize.least_squares``); the result is
mapped back to z exactly. Metrics follow MATLAB: fit = 100(1 − ‖y − ŷ‖/‖y − ȳ‖),
nAIC = log V + 2n_p/N, FPE = V(1 + n_p/N)/(1 − n_p/N), V the mean squared error on the
identification points, n_p = n + m + 1 (+1 for an estimated delay).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.polynomial import Polynomial
from numpy.polynomial import polynomial as npoly
from scipy import optimize

from aatest.plugins.analysis.polyfit import fit_percent, fpe, naic

_SK_ITERATIONS = 12
#: MINPACK's tolerances and initial step bound as ``least_squares(method="lm")`` sets them
_LM_TOL = 1e-8
_LM_FACTOR = 100.0
#: the power limit :class:`~numpy.polynomial.Polynomial` passes to ``polypow``
_MAX_POWER = Polynomial.maxpower


@dataclass(frozen=True)
class DiscreteTf:
    """A fitted discrete model: coefficients in z⁻¹ (MATLAB order) and its delay."""

    num: np.ndarray  # b0..bm
    den: np.ndarray  # 1, a1..an
    delay_samples: int
    dt: float

    @property
    def n_poles(self) -> int:
        return self.den.size - 1

    def poles(self) -> np.ndarray:
        return np.roots(self.den) if self.den.size > 1 else np.zeros(0, complex)

    def zeros(self) -> np.ndarray:
        return np.roots(self.num) if self.num.size > 1 else np.zeros(0, complex)

    def response(self, f_hz: np.ndarray) -> np.ndarray:
        """Complex frequency response at ``f_hz``."""
        zinv = np.exp(-2j * np.pi * np.asarray(f_hz) * self.dt)
        num = _polyval(zinv, self.num)
        den = _polyval(zinv, self.den)
        return zinv**self.delay_samples * num / den

    def continuous_poles(self) -> np.ndarray:
        """Pole-matched continuous equivalents s = ln(z)/T, rad/s."""
        return np.log(self.poles().astype(complex)) / self.dt


def _polyval(x: np.ndarray, coefs: np.ndarray) -> np.ndarray:
    """Σ coefs[i]·xⁱ by Horner's rule: the very operations of NumPy's ``polyval``, without its
    per-call argument checks (the output-error fit evaluates ~10⁵ of these tiny polynomials)."""
    c = np.asarray(coefs, dtype=np.float64)
    value = c[-1] + x * 0
    for coef in c[-2::-1]:
        value = coef + value * x
    return np.asarray(value)


def _w_of(f_hz: np.ndarray, dt: float, w0: float) -> np.ndarray:
    return (np.exp(2j * np.pi * f_hz * dt) - 1.0) / (w0 * dt)


def _sk_fit(w: np.ndarray, g: np.ndarray, n: int, m: int) -> tuple[np.ndarray, np.ndarray]:
    """Sanathanan–Koerner: polynomials P_b (deg m) and P_a (deg n, P_a(0) = 1) in w.

    Each iteration's solution depends only on the previous one (through the weights), so once
    a solution repeats bit for bit the iterations cycle: the last one's solution is known
    without computing the rest (≈ 45 % of the fits repeat, on average ≈ 4 iterations early).
    """
    weight = np.ones(w.size)
    iterations = _SK_ITERATIONS if n else 1
    # the unweighted columns do not change between iterations: built once
    basis = np.column_stack([w**i for i in range(m + 1)] + [-g * w**i for i in range(1, n + 1)])
    solutions: list[np.ndarray] = []
    seen: dict[bytes, int] = {}
    for k in range(iterations):
        design = basis / weight[:, None]
        rhs = g / weight
        a_real = np.vstack([design.real, design.imag])
        sol, *_ = np.linalg.lstsq(a_real, np.concatenate([rhs.real, rhs.imag]), rcond=None)
        first = seen.setdefault(sol.tobytes(), k)
        if first != k:  # iteration k repeats iteration first: a cycle of k − first
            sol = solutions[first + (iterations - 1 - first) % (k - first)]
            break
        solutions.append(sol)
        weight = np.abs(_polyval(w, np.concatenate([[1.0], sol[m + 1:]])))
    return sol[:m + 1], np.concatenate([[1.0], sol[m + 1:]])


def _refine(w: np.ndarray, g: np.ndarray, pb: np.ndarray, pa: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray]:
    """Output-error least squares on |G − P_b/P_a|² starting from the SK solution.

    The Jacobian is analytic (∂/∂b_i = −wⁱ/P_a, ∂/∂a_i = P_b·wⁱ/P_a², relative to |G|): the
    finite-difference one cost a residual per parameter per iteration, ≈ 70 % of the fit,
    and its step error only blurs the same minimum.
    """
    m1 = pb.size
    scale = 1.0 / np.abs(g)
    powers = w[:, None] ** np.arange(max(m1, pa.size))  # wⁱ, one column per power
    # the last point's polynomials, residual and Jacobian: ``leastsq`` evaluates both at the
    # start point twice (its argument check, then MINPACK), and MINPACK asks the Jacobian at
    # the point whose residual it has just evaluated (≈ 70 % of the calls)
    last: dict[str, Any] = {"theta": b""}

    def parts(theta: np.ndarray) -> dict[str, Any]:
        key = theta.tobytes()
        if last["theta"] != key:
            last.clear()
            last.update(theta=key, num=_polyval(w, theta[:m1]),
                        den=_polyval(w, np.concatenate([[1.0], theta[m1:]])))
        return last

    def residual(theta: np.ndarray) -> np.ndarray:
        at = parts(theta)
        if "residual" not in at:
            e = (g - at["num"] / at["den"]) * scale
            at["residual"] = np.concatenate([e.real, e.imag])
        return np.asarray(at["residual"])

    def jacobian(theta: np.ndarray) -> np.ndarray:
        at = parts(theta)
        if "jacobian" not in at:
            num, den = at["num"], at["den"]
            inv = scale / den
            jac = np.concatenate([-powers[:, :m1] * inv[:, None],
                                  powers[:, 1:pa.size] * (num * inv / den)[:, None]], axis=1)
            at["jacobian"] = np.concatenate([jac.real, jac.imag])
        return np.asarray(at["jacobian"])

    theta0 = np.concatenate([pb, pa[1:]])
    if theta0.size * 1 >= 2 * w.size:
        return pb, pa
    # MINPACK's lmder through ``leastsq``, with the very arguments ``least_squares(method=
    # "lm")`` passes it (tolerances 1e-8, factor 100, its default scaling ``diag=None``, ≤ 200
    # evaluations per parameter): the same iterates and solution, without least_squares'
    # wrapping of every residual and Jacobian call (≈ 30 % of the refinement; the scan
    # refines ≈ 900 models per stepped-sine run). full_output: no warning on a stop at the
    # evaluation limit, which least_squares takes silently too.
    x = optimize.leastsq(residual, theta0, Dfun=jacobian, full_output=True, ftol=_LM_TOL,
                         xtol=_LM_TOL, gtol=_LM_TOL, maxfev=200 * theta0.size,
                         factor=_LM_FACTOR, diag=None)[0]
    return x[:m1], np.concatenate([[1.0], x[m1:]])


def _to_z(p_w: np.ndarray, c: float) -> np.ndarray:
    """Coefficients (ascending powers of z) of P(w) with w = (z − 1)/c.

    The very operations of ``Σ coef·Polynomial([−1/c, 1/c])**i`` (``polypow``, ``polymul``,
    ``polyadd``, which is what :class:`~numpy.polynomial.Polynomial`'s operators call) on
    plain arrays: the same coefficients without building a ``Polynomial`` per term (the
    transfer-function scan converts ≈ 2 000 models per run).
    """
    out = np.array([0.0])
    for i, coef in enumerate(p_w):
        out = npoly.polyadd(out, npoly.polymul(coef, _zm1_power(c, i)))
    return np.asarray(out, dtype=np.float64)


@functools.lru_cache(maxsize=64)
def _zm1_power(c: float, i: int) -> np.ndarray:
    """``polypow([−1/c, 1/c], i)``: the same for every model of a group (c = ω₀T), kept
    (read-only: every caller shares it)."""
    power = npoly.polypow(np.array([-1.0 / c, 1.0 / c]), i, _MAX_POWER)
    power.flags.writeable = False
    return power


def fit_discrete_tf(f_hz: np.ndarray, h: np.ndarray, n: int, m: int, dt: float,
                    delay_samples: int = 0) -> DiscreteTf:
    """Fit H(z) with n poles, m ≤ n zeros and a fixed delay to complex FRF points."""
    if m > n:
        raise ValueError(f"m = {m} zeros > n = {n} poles")
    w0 = 2 * np.pi * float(np.max(f_hz))
    w = _w_of(f_hz, dt, w0)
    z = 1.0 + w * w0 * dt
    g = np.asarray(h) * z**delay_samples * z ** (-(n - m))
    pb, pa = _refine(w, g, *_sk_fit(w, g, n, m))
    bz, az = _to_z(pb, w0 * dt), _to_z(pa, w0 * dt)
    bz = np.pad(bz, (0, m + 1 - bz.size)) if bz.size < m + 1 else bz[:m + 1]
    az = np.pad(az, (0, n + 1 - az.size)) if az.size < n + 1 else az[:n + 1]
    lead = az[-1]
    # ascending powers of z → coefficients of z⁻ⁱ after dividing by z^n (num by z^m)
    return DiscreteTf(num=bz[::-1] / lead, den=az[::-1] / lead, delay_samples=delay_samples,
                      dt=dt)


def model_metrics(model: DiscreteTf, f_id: np.ndarray, h_id: np.ndarray, f_val: np.ndarray,
                  h_val: np.ndarray, delay_estimated: bool) -> dict[str, Any]:
    """MATLAB-style quality metrics on identification and validation points."""
    fitted_id = model.response(f_id)
    e_id = h_id - fitted_id
    v = float(np.mean(np.abs(e_id) ** 2))
    n_p = model.n_poles + model.num.size + int(delay_estimated)
    n_id = h_id.size
    poles, zeros = model.poles(), model.zeros()
    return {
        "fit_pct": fit_percent(h_val, model.response(f_val)) if h_val.size > 1 else float("nan"),
        "fit_id_pct": fit_percent(h_id, fitted_id),
        "V": v, "n_params": n_p, "N": n_id,
        "nAIC": naic(v, n_p, n_id),
        "FPE": fpe(v, n_p, n_id) if n_p < n_id else float("inf"),
        "stable": bool(np.all(np.abs(poles) < 1.0)),
        "zeros_outside_unit_circle": int(np.sum(np.abs(zeros) > 1.0)),
    }


#: the second-order-plus-delay model's parameters, in the fit's order (results.json names)
SECOND_ORDER_PARAMETERS = ("gain_v_per_dps2", "natural_frequency_hz", "damping", "delay_s")
#: their bounds: K ≥ 0, ωn ∈ [2π, 1e4] rad/s, ζ ∈ [0.05, 5], τ ∈ [−0.05, 0.2] s
_SECOND_ORDER_LOWER = np.array([0.0, 2 * np.pi, 0.05, -0.05])
_SECOND_ORDER_UPPER = np.array([np.inf, 1e4, 5.0, 0.2])
#: relative distance to a bound within which a parameter counts as held on it (the
#: solver's stopping point on a pressed bound lies ≈ 1e-6 inside; a free optimum this close
#: has a Jacobian interval that crosses the bound anyway)
BOUND_MARGIN = 1e-4
#: the trust-region fit's stopping tolerances (ftol, xtol, gtol). Why not the default 1e-8:
#: ωn, ζ and τ are strongly correlated, and at 1e-8 the solver stopped up to 1e-4 of a
#: parameter's uncertainty short of the minimum, at a point set by its path, so a change of
#: the FRF points in their 13th digit (rounding) moved ωn by 3e-5 relative
_SECOND_ORDER_TOL = 1e-15
#: Gauss–Newton steps that finish the fit (:func:`_polished`); each at least halves the
#: distance to the minimum of a fit this good, so a handful reaches rounding
_POLISH_STEPS = 8
#: a polishing step may raise the cost by this much (relative): its rounding, no more
_POLISH_COST_ROUNDING = 1e-12


def _second_order_terms(f_hz: np.ndarray, h: np.ndarray) -> tuple[
        Callable[[np.ndarray], np.ndarray], Callable[[np.ndarray], np.ndarray],
        Callable[[np.ndarray], np.ndarray]]:
    """(model, residual, Jacobian) of K·ωn²/(s² + 2ζωn·s + ωn²)·e^{−sτ} against ``h``:
    relative complex errors (h − model)/|h|, real and imaginary parts stacked.

    The Jacobian is analytic (∂/∂K = model/K, ∂/∂ωn = model·(2/ωn − (2ζs + 2ωn)/D),
    ∂/∂ζ = −model·2ωn·s/D, ∂/∂τ = −s·model, D the denominator, each over −|h|): the
    finite-difference one cost four residuals per step and carried its step error (≈ 3e-6
    relative) into the stated uncertainties.
    """
    s = 2j * np.pi * np.asarray(f_hz)
    h = np.asarray(h)
    scale = np.abs(h)

    def model(theta: np.ndarray) -> np.ndarray:
        k, wn, zeta, tau = theta
        return np.asarray(k * wn**2 / (s**2 + 2 * zeta * wn * s + wn**2) * np.exp(-s * tau))

    def residual(theta: np.ndarray) -> np.ndarray:
        e = (h - model(theta)) / scale
        return np.concatenate([e.real, e.imag])

    def jacobian(theta: np.ndarray) -> np.ndarray:
        _, wn, zeta, tau = theta
        den = s**2 + 2 * zeta * wn * s + wn**2
        unit = wn**2 / den * np.exp(-s * tau)  # the model at K = 1
        m = theta[0] * unit
        cols = np.column_stack([unit, m * (2.0 / wn - (2 * zeta * s + 2 * wn) / den),
                                -m * 2 * wn * s / den, -s * m]) / -scale[:, None]
        return np.concatenate([cols.real, cols.imag])

    return model, residual, jacobian


def _polished(residual: Callable[[np.ndarray], np.ndarray],
              jacobian: Callable[[np.ndarray], np.ndarray], x: np.ndarray,
              free: np.ndarray) -> np.ndarray:
    """``x`` after Gauss–Newton steps on the ``free`` parameters (those on a bound stay).

    Why: the trust-region solver accepts a step only when the cost falls, and near the
    minimum the fall drowns in the cost's rounding, so it stops ≈ 1e-6 of a parameter's
    uncertainty short, where its path left it. The Gauss–Newton step is set by the
    gradient, not by the cost, so a few of them end at the minimum to rounding: the fit then
    depends on the FRF points, not on how the solver got there. A step that leaves the
    bounds or raises the cost beyond rounding ends the polish.
    """
    r = residual(x)
    cost = float(r @ r)
    for _ in range(_POLISH_STEPS):
        jac = jacobian(x)[:, free]
        norm = np.linalg.norm(jac, axis=0)
        norm[norm == 0.0] = 1.0
        step = np.linalg.lstsq(jac / norm, -r, rcond=None)[0] / norm
        trial = x.copy()
        trial[free] += step
        r_trial = residual(trial)
        trial_cost = float(r_trial @ r_trial)
        inside = bool(np.all(trial >= _SECOND_ORDER_LOWER) and np.all(trial <= _SECOND_ORDER_UPPER))
        if not (inside and trial_cost <= cost * (1.0 + _POLISH_COST_ROUNDING)):  # NaN: stop
            break
        x, r, cost = trial, r_trial, trial_cost
        if np.all(np.abs(step) <= 1e-15 * np.abs(x[free])):
            break
    return x


def second_order_delay_fit(f_hz: np.ndarray, h: np.ndarray, delay0_s: float) -> dict[str, Any]:
    """Fit K·ωn²/(s² + 2ζωn·s + ωn²)·e^{−sτ} to FRF points (K, ωn, ζ, τ; relative errors).

    Started from a grid of natural frequencies (5–200 Hz) with ζ = 0.7 and the cross-correlation
    delay split between dynamics and transport; the best local solution is kept and finished
    by Gauss–Newton steps (:func:`_polished`). Standard uncertainties come from the Jacobian at
    the solution, for the parameters not held on a bound (ζ ∈ [0.05, 5], τ ∈ [−0.05, 0.2] s,
    fn ∈ [1, 1592] Hz); those on a bound are named in ``at_bound`` and their uncertainty is
    ``None``.
    """
    model, residual, jacobian = _second_order_terms(f_hz, h)
    k0 = float(np.abs(np.asarray(h)[np.argmin(f_hz)]))
    best = None
    for fn in (5.0, 10.0, 20.0, 40.0, 80.0, 160.0):
        wn = 2 * np.pi * fn
        tau0 = max(delay0_s - 1.4 / wn, 0.0)
        sol = optimize.least_squares(residual, [k0, wn, 0.7, tau0], jac=jacobian, method="trf",
                                     bounds=(_SECOND_ORDER_LOWER, _SECOND_ORDER_UPPER),
                                     ftol=_SECOND_ORDER_TOL, xtol=_SECOND_ORDER_TOL,
                                     gtol=_SECOND_ORDER_TOL)
        if best is None or sol.cost < best.cost:
            best = sol
    assert best is not None
    # a parameter held on its bound is not estimated: the curvature there says nothing of
    # its uncertainty (and, with ζ at 5, ωn and ζ are nearly degenerate: an overdamped pair
    # is identified only through its slow pole), so the free parameters' covariance is taken
    # with it fixed and its own uncertainty is not stated
    free = ~_on_bound(best.x, best.active_mask)
    x = _polished(residual, jacobian, np.asarray(best.x, dtype=np.float64), free)
    r = residual(x)
    dof = max(r.size - int(free.sum()), 1)
    u = np.full(free.size, np.nan)
    u[free] = np.sqrt(np.diag(_covariance(jacobian(x)[:, free])) * float(r @ r) / dof)
    k, wn, zeta, tau = x
    return {"gain_v_per_dps2": float(k), "natural_frequency_hz": float(wn / (2 * np.pi)),
            "damping": float(zeta), "delay_s": float(tau),
            "u_natural_frequency_hz": _stated(u[1] / (2 * np.pi)), "u_damping": _stated(u[2]),
            "u_delay_s": _stated(u[3]), "fit_pct": fit_percent(h, model(x)),
            "at_bound": [name for name, f in zip(SECOND_ORDER_PARAMETERS, free, strict=True)
                         if not f]}


def _on_bound(x: np.ndarray, active_mask: np.ndarray) -> np.ndarray:
    """Which parameters the fit holds on a bound: the solver's active set, or within
    :data:`BOUND_MARGIN` of a bound (``trf`` keeps its iterates strictly inside and stops
    ≈ 1e-6 short of a bound it presses on, reporting it free)."""
    near = [np.isfinite(b) & (np.abs(x - b) <= BOUND_MARGIN * np.abs(b))
            for b in (_SECOND_ORDER_LOWER, _SECOND_ORDER_UPPER)]
    return (np.asarray(active_mask) != 0) | near[0] | near[1]


def _covariance(jac: np.ndarray) -> np.ndarray:
    """(JᵀJ)⁻¹ by the SVD of the column-equilibrated Jacobian, without truncation.

    A pseudo-inverse drops a near-degenerate direction — the one along which the data do not
    tell two parameters apart — and so states it as *certain*; the full inverse states it as
    what it is, uncertain (an exactly degenerate direction gives an infinite variance).
    """
    norm = np.linalg.norm(jac, axis=0)
    norm[norm == 0.0] = 1.0
    _, sv, vt = np.linalg.svd(jac / norm, full_matrices=False)
    with np.errstate(divide="ignore"):
        scaled = (vt.T / sv**2) @ vt
    return np.asarray(scaled / np.outer(norm, norm))


def _stated(u: float) -> float | None:
    """An uncertainty for the results (``None``: not stated — its parameter is on a bound,
    or the data cannot separate it from another, an infinite variance)."""
    return float(u) if np.isfinite(u) else None


def time_domain_fit(model: DiscreteTf, records: list[tuple[np.ndarray, np.ndarray]],
                    settle_samples: int = 0) -> float:
    """Fit % (NRMSE, MATLAB's ``compare``) of ``model`` simulated in the time domain.

    Each record is (input, output) on one time grid — the table's acceleration estimate in
    °/s² and the sensor's volts, as the study's time-domain estimation used them, so the
    estimate's noise passes through the model like any input. Means are removed; the first
    ``settle_samples`` of each simulated record (the model's start-up) are left out; the fit
    is over every record's remaining samples together: 100·(1 − ‖y − ŷ‖/‖y − ȳ‖).
    """
    from scipy import signal

    err = den = 0.0
    for u_in, y_out in records:
        u = np.asarray(u_in, dtype=np.float64) - float(np.mean(u_in))
        y = np.asarray(y_out, dtype=np.float64) - float(np.mean(y_out))
        # second-order sections: poles within 0.03 rad of z = 1 defeat a direct-form filter
        y_hat = (signal.sosfilt(signal.tf2sos(model.num, model.den), u) if model.n_poles
                 else float(model.num[0]) * u)
        d = model.delay_samples
        y_hat = np.concatenate([np.zeros(d), y_hat[:y_hat.size - d]]) if d else y_hat
        keep = slice(settle_samples + d, None)
        err += float(np.sum((y[keep] - y_hat[keep]) ** 2))
        den += float(np.sum(y[keep] ** 2))
    return float(100.0 * (1.0 - np.sqrt(err / den))) if den > 0 else float("nan")
