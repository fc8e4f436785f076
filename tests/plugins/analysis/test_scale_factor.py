"""Scale-factor calibration against synthetic recordings with a known sensor."""

from __future__ import annotations

import pytest
from synthetic_rig import SynthRig, SynthSensor, make_dataset, sine_step

from aatest.engine.analysis.passes import run_analysis


@pytest.mark.parametrize("c3, order", [(0.0, 1), (0.02, 3)], ids=["linear", "cubic"])
def test_scale_and_offset_recovered(c3: float, order: int) -> None:
    sensor = SynthSensor(scale_v_per_dps2=0.00398, bias_v=2.4971, c3=c3, delay_s=0.006)
    data = make_dataset([sine_step("cal", 16, 400.0, samples=32768)], SynthRig(sensors=(sensor,)))
    out = run_analysis("scale_factor", data)
    v = out.result["v_sz"].model_dump()
    # the scale factor is the best straight line: a cubic raises it by ¾·c3·(A/range)²
    best_line = sensor.scale_v_per_dps2 * (1 + 0.75 * c3 * (400.0 / sensor.range_dps2) ** 2)
    assert v["scale_v_per_dps2"] == pytest.approx(best_line, rel=1e-3)
    # the chosen model's linear term is the small-signal sensitivity
    assert 1 / v["coefficients"][1] == pytest.approx(sensor.scale_v_per_dps2, rel=2e-3)
    assert v["offset_v"] == pytest.approx(sensor.bias_v, abs=1e-4)
    assert v["order"] == order
    assert v["alignment_delay_s"] == pytest.approx(0.006 + 0.0036, abs=5e-4)
    assert {"rmse_dps2", "coefficients", "ci95"} <= set(v)
    assert v["reference"] == "smoothed"  # the default, named for the certificate
    assert out.figures["scale_factor_v_sz"].lstrip().startswith("<?xml")


def test_correlation_inflation_of_white_and_coloured_residuals() -> None:
    """White residuals inflate nothing; AR(1) residuals with coefficient φ inflate the variance
    of a mean-like estimate by (1 + φ)/(1 − φ) (their integrated autocorrelation)."""
    import numpy as np
    from scipy import signal

    from aatest.plugins.analysis.scale_factor import correlation_inflation

    rng = np.random.default_rng(7)
    white = rng.standard_normal(200_000)
    assert correlation_inflation(white) == pytest.approx(1.0, abs=0.05)
    phi = 0.8
    coloured = signal.lfilter([1.0], [1.0, -phi], white)
    assert correlation_inflation(coloured) == pytest.approx((1 + phi) / (1 - phi), rel=0.1)


def test_scale_interval_converts_back_to_its_standard_uncertainty() -> None:
    """``scale_ci95`` is built with the factor ``ci_std`` divides by (Z95): the standard
    uncertainty the budget reads back from the interval is the fit's own. With the GUM's
    rounded 1.96 it came back 1.96/1.959964 = 1 + 1.8e-5 too large."""
    import numpy as np

    from aatest.metrology.uncertainty.statistics import ci_std
    from aatest.plugins.analysis.scale_factor import calibrate

    rng = np.random.default_rng(5)
    ref = 400.0 * np.sin(np.linspace(0.0, 20 * np.pi, 4000))
    volts = 2.5 + 0.004 * ref + rng.normal(0.0, 1e-3, ref.size)
    result = calibrate(volts, ref)
    u = result["scale_u_v_per_dps2"]
    # the half-width is the difference of two numbers ≈ scale: rounding leaves ε·scale/u of
    # u, ≲ 1e-11 here (u ≈ 1e-5 of the scale); 1e-9 still sees the 1.8e-5 of a mixed factor
    assert ci_std(result["scale_ci95"]) == pytest.approx(u, rel=1e-9)
