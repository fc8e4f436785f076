"""tfest-style discrete models on exact and noisy FRF points."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from aatest.plugins.analysis.tf_models import continuous_equivalent, estimate
from aatest.plugins.analysis.tfest import fit_discrete_tf, model_metrics, second_order_delay_fit

FS = 2000.0
#: the 28 published stepped-sine points (docs/method.md §4.4)
F28 = np.array([0.396728516, 0.473022461, 0.579833984, 0.686645508, 0.823974609, 0.991821289,
                1.007080078, 1.190185547, 1.434326172, 1.708984375, 1.998901367, 2.059936523,
                2.487182617, 2.975463867, 3.005981445, 3.570556641, 3.997802734, 4.272460938,
                5.004882813, 5.142211914, 5.996704102, 6.164550781, 7.003784180, 7.400512695,
                7.995605469, 8.880615234, 9.002685547, 9.994506836])


def _second_order(fn_hz: float, zeta: float, delay: int) -> tuple[np.ndarray, np.ndarray]:
    wn = 2 * np.pi * fn_hz
    b, a = signal.bilinear([0.004 * wn**2], [1, 2 * zeta * wn, wn**2], fs=FS)
    zinv = np.exp(-2j * np.pi * F28 / FS)
    h = zinv**delay * np.polyval(b[::-1], zinv) / np.polyval(a[::-1], zinv)
    return h, a


def test_exact_model_recovered() -> None:
    h, a = _second_order(30.0, 0.9, 3)
    model = fit_discrete_tf(F28, h, 2, 2, 1 / FS, 3)
    np.testing.assert_allclose(np.sort_complex(model.poles()), np.sort_complex(np.roots(a)),
                               atol=1e-6)
    m = model_metrics(model, F28, h, F28, h, True)
    assert m["fit_pct"] > 99.99 and m["stable"]
    ct = continuous_equivalent(model)
    assert ct["natural_frequencies_hz"][0] == pytest.approx(30.0, rel=1e-3)


def test_model_selection_on_noisy_points() -> None:
    h, _ = _second_order(30.0, 0.9, 3)
    rng = np.random.default_rng(4)
    h = h * (1 + rng.normal(0, 2e-4, h.size) + 1j * rng.normal(0, 2e-4, h.size))
    _model, rows, k = estimate(F28, h, 1 / FS, {"delay_samples": 22, "accepted": True,
                                               "strength": 0.99, "delay_s": 0.011})
    best = rows[k]
    assert best["fit_pct"] > 98.0 and best["stable"]
    assert len({(r["n"], r["m"]) for r in rows}) == 21
    assert best["zeros_outside_unit_circle"] == 0
    phys = second_order_delay_fit(F28, h, 0.011)
    assert phys["natural_frequency_hz"] == pytest.approx(30.0, rel=0.05)
    # the bilinear map keeps the analogue phase (only warps frequency): delay = 3 samples
    assert phys["delay_s"] == pytest.approx(3 / FS, abs=0.25e-3)


def test_antialias_corner_sources() -> None:
    from pathlib import Path

    from aatest.engine.interfaces import AnalysisContext
    from aatest.plugins.analysis.tf_models import TransferFunctionOptions
    from aatest.plugins.analysis.transfer_function import logger_antialias_hz
    from aatest.recording.dataset import Dataset

    def ds(meta: dict) -> Dataset:  # type: ignore[type-arg]
        return Dataset("p", FS, (), (), Path("x"), meta)

    given = AnalysisContext(options=TransferFunctionOptions(antialias_hz=80))
    assert logger_antialias_hz(ds({}), given) == 80.0
    assert logger_antialias_hz(ds({"rig": {"daq": {"plugin": "can", "antialias_hz": 50}}}),
                               AnalysisContext()) == 50.0
    assert logger_antialias_hz(ds({"rig": {"daq": {"plugin": "sim"}}}), AnalysisContext()) == 100.0
    assert logger_antialias_hz(ds({"rig": {"daq": {"plugin": "can"}}}), AnalysisContext()) is None
    none = AnalysisContext(options=TransferFunctionOptions(antialias_hz="none"))
    assert logger_antialias_hz(ds({"rig": {"daq": {"plugin": "sim"}}}), none) is None


def _continuous(fn_hz: float, zeta: float, delay_s: float) -> np.ndarray:
    s = 2j * np.pi * F28
    wn = 2 * np.pi * fn_hz
    return 0.004 * wn**2 / (s**2 + 2 * zeta * wn * s + wn**2) * np.exp(-s * delay_s)


def test_second_order_free_fit_states_every_uncertainty() -> None:
    rng = np.random.default_rng(11)
    h = _continuous(30.0, 0.7, 0.002) * (1 + rng.normal(0, 1e-3, F28.size))
    phys = second_order_delay_fit(F28, h, 0.007)
    assert phys["at_bound"] == []
    assert phys["damping"] == pytest.approx(0.7, rel=0.2)
    # the stated u is a 1σ of the points' 1e-3 relative noise: the truth lies within 4σ
    for name in ("natural_frequency_hz", "damping", "delay_s"):
        assert phys[f"u_{name}"] is not None and phys[f"u_{name}"] > 0
    assert abs(phys["natural_frequency_hz"] - 30.0) < 4 * phys["u_natural_frequency_hz"]


def test_second_order_fit_on_its_damping_bound_states_no_uncertainty_for_it() -> None:
    # an overdamped pair (ζ = 12, beyond the fit's bound of 5) seen up to 10 Hz: the fit
    # holds ζ on the bound, where the Jacobian's curvature bounds nothing
    h = _continuous(200.0, 12.0, 0.001)
    phys = second_order_delay_fit(F28, h, 0.012)
    assert phys["damping"] == pytest.approx(5.0, abs=1e-6)
    assert phys["at_bound"] == ["damping"]
    assert phys["u_damping"] is None
    # the parameters left free keep a stated (conditional) uncertainty
    assert phys["u_delay_s"] is not None and phys["u_natural_frequency_hz"] is not None
