"""Report plots made from the typed results with matplotlib (Agg/SVG, no pyplot state).

Used where the analysis plugins gave no figure of their own: the calibration curve with its
95 % band and residual view, the Bode plot of the FRF points with the fitted transfer
function (extrapolated), bias against temperature per branch, and the misalignment cross
responses in the complex plane. Every function returns an SVG string or None when the results
lack the data; units follow the contract keys (V, °/s², dB, deg, °C).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np
from scipy import signal

from aatest.numerics import Z95
from aatest.presentation.figures import STYLE, to_svg
from aatest.results.frf import FrfPoint
from aatest.results.misalignment import SetSensor
from aatest.results.quantities import finite
from aatest.results.scale_factor import ScaleFactorChannel
from aatest.results.sensor import SensorInfo
from aatest.results.temperature import TemperatureChannel
from aatest.results.transfer_function import TfModel

if TYPE_CHECKING:  # matplotlib is imported when a plot is drawn (aatest.presentation.figures)
    from matplotlib.figure import Figure
    from matplotlib.typing import RcKeyType

#: applied per plot (never globally, other plugins draw with matplotlib too): text kept as
#: text, a compact font; the SVG itself is rendered by aatest.presentation.figures
_STYLE: dict[RcKeyType, Any] = dict(STYLE)
#: a line needs two points; a complex number is stated as [re, im]
_PAIR = 2

_Plot = TypeVar("_Plot", bound=Callable[..., "str | None"])


def _styled(plot: _Plot) -> _Plot:
    """Run a plot function inside the report style."""

    @functools.wraps(plot)
    def wrapper(*args: Any, **kwargs: Any) -> str | None:
        import matplotlib

        with matplotlib.rc_context(_STYLE):
            return plot(*args, **kwargs)

    return wrapper  # type: ignore[return-value]


def _svg(fig: Figure) -> str:
    return to_svg(fig)


def _figure(width_in: float, height_in: float) -> Figure:
    """A constrained-layout figure (matplotlib imported only now)."""
    from matplotlib.figure import Figure

    return Figure(figsize=(width_in, height_in), layout="constrained")


def _poly_band(entry: ScaleFactorChannel, n_coef: int, u_v: np.ndarray) -> np.ndarray | None:
    """Standard deviation of y(u) = Σ a_i u^i (°/s²): φᵀΣφ with the fit's covariance when
    it matches the coefficients, else from the coefficients' ci95 taken as independent."""
    powers = np.vander(u_v, n_coef, increasing=True)
    cov = np.asarray(entry.fit.covariance, dtype=float)
    if cov.shape == (n_coef, n_coef):
        return np.sqrt(np.clip(np.einsum("ij,jk,ik->i", powers, cov, powers), 0.0, None))
    stds = [abs(ci[1] - ci[0]) / (2 * Z95) if len(ci) == _PAIR else math.nan
            for ci in entry.ci95[:n_coef]]
    if len(stds) != n_coef or not all(math.isfinite(s) for s in stds):
        return None
    return np.sqrt((powers**2) @ np.square(np.asarray(stds, dtype=float)))


@_styled
def calibration_curve(entry: ScaleFactorChannel, sensor: SensorInfo,
                      peak_dps2: float | None = None) -> str | None:
    """Fitted y(u) over the calibrated span (±``peak_dps2``) with its 95 % band, and the
    residual view below.

    Without per-sample residuals in the results, the lower panel shows what the polynomial
    adds to its best straight line (the non-linearity) against the ±RMSE band.
    """
    coefficients = [float(c) for c in entry.coefficients]
    if len(coefficients) < _PAIR:
        return None
    k_v = finite(entry.scale_v_per_dps2) or 1.0 / coefficients[1]
    # stay inside the calibrated span: a high-order polynomial is not an extrapolator
    peak = peak_dps2 or 0.7 * sensor.range_dps2
    u_v = np.linspace(-peak * k_v, peak * k_v, 201)
    y = np.polynomial.polynomial.polyval(u_v, coefficients)
    band = _poly_band(entry, len(coefficients), u_v)
    fig = _figure(6.4, 4.6)
    top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=[2, 1])
    top.plot(u_v, y, color="C0", label=f"order {len(coefficients) - 1} fit")
    if band is not None:
        top.fill_between(u_v, y - Z95 * band, y + Z95 * band, color="C0", alpha=0.25,
                         label="95 % band (coefficients)")
    top.set_ylabel("reference α (°/s²)")
    top.legend(loc="upper left")
    deviation = y - np.polyval(np.polyfit(u_v, y, 1), u_v)
    bottom.plot(u_v, deviation, color="C1", label="fit − best line")
    if band is not None:
        bottom.fill_between(u_v, deviation - Z95 * band, deviation + Z95 * band,
                            color="C1", alpha=0.25)
    rmse = finite(entry.rmse_dps2)
    if rmse:
        bottom.axhspan(-rmse, rmse, color="C2", alpha=0.15, label=f"±RMSE {rmse:.3g} °/s²")
    bottom.set_xlabel("sensor output − bias (V)")
    bottom.set_ylabel("residual (°/s²)")
    bottom.legend(loc="upper left", fontsize=7)
    return _svg(fig)


def _model_response(tf: TfModel | None, f_hz: np.ndarray) -> np.ndarray | None:
    if tf is None or not tf.num or not tf.den or not finite(tf.dt):
        return None
    _, h = signal.freqz(np.asarray(tf.num, float), np.asarray(tf.den, float), worN=f_hz,
                        fs=1.0 / tf.dt)
    delay = finite(tf.delay_s) or 0.0
    return h * np.exp(-2j * np.pi * f_hz * delay)


@_styled
def bode(points: Sequence[FrfPoint], tf: TfModel | None,
         gain_u_db: Sequence[float] | None = None) -> str | None:
    """FRF points (with ±U gain bars) and the fitted model, extrapolated to 5× the last point."""
    keep = [i for i, p in enumerate(points) if finite(p.gain_db) is not None]
    if not keep:
        return None
    rows = [points[i] for i in keep]
    u_db = np.asarray(gain_u_db, dtype=float)[keep] if gain_u_db is not None else None
    f = np.array([p.frequency_hz for p in rows])
    gain = np.array([p.gain_db for p in rows])
    phase = np.array([finite(p.phase_deg) or np.nan for p in rows])
    groups = np.array([p.group or "FRF points" for p in rows])
    fig = _figure(6.4, 4.8)
    ax_g, ax_p = fig.subplots(2, 1, sharex=True)
    for i, group in enumerate(dict.fromkeys(groups)):  # one colour per test group
        sel = groups == group
        ax_g.errorbar(f[sel], gain[sel], yerr=None if u_db is None else u_db[sel], fmt="o",
                      ms=3, capsize=2, color=f"C{i + 1}", label=f"{group} (±U)")
        ax_p.plot(f[sel], phase[sel], "o", ms=3, color=f"C{i + 1}")
    fm = np.geomspace(f.min() / 2, f.max() * 5, 300)
    model = _model_response(tf, fm)
    if model is not None:
        ax_g.plot(fm, 20 * np.log10(np.abs(model)), "C0", label="fitted model")
        ax_p.plot(fm, np.degrees(np.unwrap(np.angle(model))), "C0")
    ax_g.set_xscale("log")
    ax_g.set_ylabel("gain (dB V per °/s²)")
    ax_g.legend(loc="lower left", fontsize=7)
    ax_p.set_ylabel("phase (°)")
    ax_p.set_xlabel("frequency (Hz)")
    return _svg(fig)


@_styled
def bias_vs_temperature(entry: TemperatureChannel) -> str | None:
    """Bias per temperature point, by branch, with the fitted slope (mV/°C)."""
    temps, biases = entry.temperatures_c or [], entry.bias_v or []
    if len(temps) != len(biases):
        return None
    stated = entry.branch or []
    branch_of = list(stated) if len(stated) == len(biases) else ["all"] * len(biases)
    points = [(t, b, br) for t, b, br in zip(temps, biases, branch_of, strict=True)
              if finite(t) is not None and finite(b) is not None]
    if len(points) < _PAIR:
        return None
    fig = _figure(6.4, 3.4)
    ax = fig.subplots()
    for i, branch in enumerate(sorted({p[2] for p in points})):
        sel = [p for p in points if p[2] == branch]
        ax.plot([p[0] for p in sel], [1e3 * p[1] for p in sel], "o-", color=f"C{i}", ms=4,
                label=branch)
    t = np.array([p[0] for p in points])
    slope, intercept = np.polyfit(t, [p[1] for p in points], 1)
    tt = np.linspace(t.min(), t.max(), 2)
    ax.plot(tt, 1e3 * (slope * tt + intercept), "k--", lw=1, label=f"{slope * 1e3:.3f} mV/°C")
    ax.set_xlabel("temperature (°C)")
    ax.set_ylabel("bias (mV)")
    ax.legend(fontsize=7)
    return _svg(fig)


def _relative_cross(entry: SetSensor) -> complex | None:
    """ΔA relative to the sensitive response's magnitude |A_z| (≈ sin δ_e), or raw ΔA."""
    if len(entry.delta_A) != _PAIR:
        return None
    cross = complex(entry.delta_A[0], entry.delta_A[1])
    main = complex(*entry.A_z) if len(entry.A_z) == _PAIR else 0j
    return cross / abs(main) if abs(main) > 0 else cross


@_styled
def misalignment_plane(sets: Mapping[str, Mapping[str, SetSensor]]) -> str | None:
    """Non-sensitive resultants ΔA of every set and sensor in the complex plane, in % of the
    sensitive response |A_z|."""
    drawn = [(i, sensor, label, z)
             for i, sensor in enumerate(("SZ", "SY", "SX"))
             for label, block in sorted(sets.items()) if sensor in block
             for z in [_relative_cross(block[sensor])] if z is not None]
    if not drawn:
        return None
    fig = _figure(5.0, 4.2)
    ax = fig.subplots()
    for i, sensor, label, z in drawn:
        pivoted = "ABCDEFGH".find(label) % 2 == 1
        xy = (100.0 * z.real, 100.0 * z.imag)
        ax.plot(*xy, "s" if pivoted else "o", color=f"C{i}", mfc="none" if pivoted else f"C{i}",
                label=sensor if label == "A" else None)
        ax.annotate(label, xy, fontsize=6)
    ax.axhline(0, color="0.7", lw=0.5)
    ax.axvline(0, color="0.7", lw=0.5)
    ax.set_xlabel("Re ΔA (% of |A_z|)")
    ax.set_ylabel("Im ΔA (% of |A_z|)")
    ax.set_title("filled: original, open: pivoted", fontsize=8)
    ax.legend(fontsize=7)
    return _svg(fig)


def _number(value: Any) -> float | None:
    """A finite float of a diagnosis document's value, else None."""
    return finite(float(value)) if isinstance(value, int | float) else None


@_styled
def diagnosis_bars(diagnosis: Mapping[str, Any]) -> str | None:
    """Candidates' ΔBIC (accepted highlighted) and the RMSE before/after the findings."""
    candidates = [c for c in diagnosis.get("candidates") or []
                  if isinstance(c, Mapping) and _number(c.get("delta_bic")) is not None]
    gain = diagnosis.get("gain") or {}
    if not candidates and not gain:
        return None
    fig = _figure(6.4, 3.2)
    ax_c, ax_g = fig.subplots(1, 2, width_ratios=[3, 1])
    names = [str(c["effect"]) for c in candidates]
    values = [float(c["delta_bic"]) for c in candidates]
    colors = ["C2" if c.get("accepted") else "0.6" for c in candidates]
    ax_c.barh(names, values, color=colors)
    ax_c.set_xlabel("ΔBIC (negative = supported)")
    before, after = _number(gain.get("rmse_v_before")), _number(gain.get("rmse_v_after"))
    if before is not None and after is not None:
        ax_g.bar(["before", "after"], [1e3 * before, 1e3 * after], color=["0.6", "C2"])
        ax_g.set_ylabel("RMSE (mV)")
    return _svg(fig) if (names or before is not None) else None


@_styled
def residual_steps(view: Mapping[str, Any], max_steps: int = 40) -> str | None:
    """RMS of measured − simulated per step, nominal vs extended model (mV)."""
    rows = [r for r in view.get("per_step") or [] if isinstance(r, Mapping)
            and _number(r.get("rms_v_nominal")) is not None][:max_steps]
    if not rows:
        return None
    names = [str(r.get("step", i)) for i, r in enumerate(rows)]
    before = np.array([1e3 * float(r["rms_v_nominal"]) for r in rows])
    after = np.array([1e3 * (_number(r.get("rms_v_extended")) or np.nan) for r in rows])
    fig = _figure(6.4, 1.2 + 0.22 * len(rows))
    ax = fig.subplots()
    y = np.arange(len(rows))
    ax.barh(y - 0.2, before, height=0.4, color="0.6", label="nominal simulation")
    ax.barh(y + 0.2, after, height=0.4, color="C2", label="extended model (named + generic)")
    ax.set_yticks(y, names, fontsize=6)
    ax.invert_yaxis()
    ax.set_xlabel("residual RMS (mV)")
    ax.legend(fontsize=7)
    return _svg(fig)
