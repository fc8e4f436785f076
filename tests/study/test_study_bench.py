"""The twin against the study's measured results (``bench/study.py``, docs/method.md).

The cheapest rows run by default: the FRF roll-off at 9.99 Hz at two accelerations (the
study: 0.5 dB at 10 °/s², 0.2 dB at 400 °/s², tolerance ± 0.15 dB) and the (non)linearity L
of Eq. 3.36 against the twin's own truth. Every row of the bench runs under ``-m slow``: the
rows within tolerance must stay within, the rows the twin misses are listed with their cause.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest

from aatest.engine.analysis.passes import run_analysis
from aatest.plugins.analysis._common import fundamental
from aatest.twin.api import realistic_rig_model, simulate_dataset

_BENCH = Path(__file__).resolve().parents[2] / "bench" / "study.py"
#: FRF roll-off tolerance of the comparison (issue 28), dB
ROLL_OFF_TOL_DB = 0.15


def _bench() -> ModuleType:
    spec = importlib.util.spec_from_file_location("study_bench", _BENCH)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses resolve their module by name
    spec.loader.exec_module(module)
    return module


bench = _bench()


@pytest.mark.parametrize("accel", [10.0, 400.0])
def test_frf_roll_off_at_the_highest_frequency(accel: float) -> None:
    """The flat level from the 0.99 Hz point (the bench averages every point ≤ 1 Hz; at
    10 and 400 °/s² they agree within 0.01 dB) against the 9.99 Hz point, seed 7."""
    steps = [s for s in bench._accel_steps() if s.accel_dps2 == accel
             and (abs(s.frequency_hz - 0.9918) < 1e-3 or abs(s.frequency_hz - 9.9945) < 1e-3)]
    assert len(steps) == 2
    points = bench.frf_points(realistic_rig_model(), 7, steps)[accel]
    assert bench.roll_off_db(points) == pytest.approx(bench.ROLL_OFF_DB[accel],
                                                      abs=ROLL_OFF_TOL_DB)


def test_linearity_l_of_both_models_against_the_twin_truth() -> None:
    """L (Eq. 3.36) on the study's scale-factor record (1 Hz, 400 °/s², 70 s, seed 7).

    Against the table's own estimate the 1st-order model *is* the ideal line: L = 0 to the
    arithmetic's rounding. Against the sliding-mode reference the cubic model carries the
    twin's cubic non-linearity (c3 = 0.002): f − g = c3·A³/(4·R²)·sin 3θ over the sine, RMS
    c3·A³/(4√2·R²) = 0.0689 °/s² (A = 400 °/s², R = 572.958 °/s²), and the quadratic of the
    rotor's jerk distortion (0.118 °/s², together 0.137); 30 % (the comparison's tolerance)
    covers the reference noise the model picks up (measured 0.140). The study
    measured 0.464 and 1.261 °/s²: the twin does not reproduce them (see the slow test).
    """
    data = simulate_dataset(realistic_rig_model(), bench._plan("scale-factor.yaml"), 7)
    table = run_analysis("scale_factor", data, {"reference": "table_estimate",
                                                "orders": (1, 1)}).result["v_sz"]
    assert table.linearity_l_dps2 is not None and abs(table.linearity_l_dps2) < 1e-9
    sliding = run_analysis("scale_factor", data, {"reference": "sliding_mode",
                                                  "orders": (3, 3)}).result["v_sz"]
    cubic = 0.002 * 400.0**3 / (4 * 2**0.5 * 572.958**2)
    # the rotor's jerk distortion c·j² = c·ω²A²·cos²θ is quadratic in α, −c·ω²·α² + const:
    # RMS c·ω²A²/(2√2) from the line (0.118 °/s² at 1 Hz), orthogonal to the cubic's sin 3θ
    sensor = realistic_rig_model().sensors[0]
    assert sensor.jerk_distortion is not None
    c_dps2 = sensor.jerk_distortion.coefficient_v_per_dps3_squared / sensor.scale_v_per_dps2
    w = 2 * np.pi * float(data.steps[0].step.frequency_hz or 0.0)
    truth = float(np.hypot(cubic, c_dps2 * (w * 400.0) ** 2 / (2 * 2**0.5)))
    assert sliding.linearity_l_dps2 == pytest.approx(truth, rel=0.3)


def test_lag_input_shifts_the_pairs_and_the_frf_points_by_whole_samples() -> None:
    """Pure sines, the output 20 samples behind a noisy input, 8192 samples at 2 kHz: paired
    12 samples late, the input leaves 8 samples between them, in the records (their fundamental
    ratio, over whole cycles: the window's leakage is the same for both, so ≤ 1e-3 samples) and
    in the FRF points (a phase ramp, exact to rounding); the input keeps its noise (a shift)."""
    fs, n, delay, lag = 2000.0, 8192, 20, 12
    f_hz = np.array([c * fs / n for c in (5, 11, 23, 41)])
    t = np.arange(n) / fs
    rng = np.random.default_rng(7)
    records = [(np.sin(2 * np.pi * f * t) + 0.1 * rng.standard_normal(n),
                np.sin(2 * np.pi * f * (t - delay / fs))) for f in f_hz]
    h = np.exp(-2j * np.pi * f_hz * delay / fs)
    design = bench.TfDesign(f_hz, h, np.array([0, 2]), np.array([1, 3]), [records[1], records[3]],
                            1 / fs, [records[0], records[2]])
    lagged = bench.lag_input(design, lag)
    left = -np.angle(lagged.h) / (2 * np.pi * f_hz) * fs
    np.testing.assert_allclose(left, delay - lag, rtol=1e-9)
    for (u, y), (u0, _), f in zip(lagged.records, design.records, f_hz[[1, 3]], strict=True):
        assert u.size == y.size == n - lag
        np.testing.assert_array_equal(u, u0[:-lag])
        ratio = fundamental(y, f, fs) / fundamental(np.sin(2 * np.pi * f * t[:-lag]), f, fs)
        assert -np.angle(ratio) / (2 * np.pi * f) * fs == pytest.approx(delay - lag, abs=1e-3)
    assert bench.lag_input(design, 0) is design


def _tf00_from_fundamentals(design: Any, gain: float) -> float:
    """TF00 fit % as the records' fundamentals and the input's noise predict it: per record
    |Y − g·X|²/2 + g²·σ² of error power against |Y|²/2 of output power (σ: the input less its
    mean and six fitted harmonics)."""
    fs = 1.0 / design.dt
    err = power = 0.0
    for (u, y), f in zip(design.records, design.f_hz[design.valid], strict=True):
        x_f, y_f = fundamental(u, f, fs), fundamental(y, f, fs)
        t = np.arange(u.size) / fs
        harmonics = [g(2 * np.pi * k * f * t) for k in range(1, 7) for g in (np.sin, np.cos)]
        basis = np.column_stack([np.ones_like(t), *harmonics])
        coef, *_ = np.linalg.lstsq(basis, u, rcond=None)
        err += abs(y_f - gain * x_f) ** 2 / 2 + gain**2 * float(np.var(u - basis @ coef))
        power += abs(y_f) ** 2 / 2
    return float(100 * (1 - np.sqrt(err / power)))


@pytest.mark.slow
def test_tf00_is_what_the_frf_phase_and_the_input_noise_leave() -> None:
    """The 400 °/s² design, seed 7 (4 min on a loaded machine): TF00 in the time domain equals its
    prediction from the fundamentals and the estimate's noise alone, at the FRF's alignment and
    with the input 12 samples late — so no effect that keeps the FRF phase can move it.
    Neglected: the output's harmonics (≈ 1.5 % RMS, 0.03 points in quadrature with a 36 %
    error) and noise (1 mV on 1.1 V); 0.3 points bounds them. At the FRF's alignment (24.3
    samples) it stays below the 66 % a 24-sample lag allows; 12 samples late it is the study's
    78.56 ± 1.5."""
    from aatest.plugins.analysis.tfest import fit_discrete_tf, time_domain_fit

    base = bench.tf_design(realistic_rig_model(), 7)
    fits = {}
    for lag in (0, 12):
        design = bench.lag_input(base, lag)
        gain = fit_discrete_tf(design.f_hz[design.ident], design.h[design.ident], 0, 0,
                               design.dt)
        fits[lag] = time_domain_fit(gain, design.records, settle_samples=2000)
        assert fits[lag] == pytest.approx(_tf00_from_fundamentals(design, float(gain.num[0])),
                                          abs=0.3)
    assert fits[0] < 66.0
    assert fits[12] == pytest.approx(bench.TF00_FIT, abs=1.5)


#: rows the twin misses, by name prefix, with the cause found (issue 28's closing note)
KNOWN_MISSES = {
    "table_estimate: L": "a straight-line model is its own ideal line (L = 0); the study's "
                         "0.464 needs its Eq. 3.36 construction, not in the method brief",
    "sliding_mode: linear term": "the study's pair 255.1 / L 1.261 needs L ≥ 1.82 under Eq. "
                                 "3.36; only a unit outside its datasheet gives both "
                                 "(bench/study_linearity.py)",
    "sliding_mode: L": "same: one sensor curvature cannot give both study L values",
    "gain starts to fall": "the default has no stiction gap; realistic_rig_model(stiction=True) "
                           "meets the fall and delay rows (bench/study_lowamp.py) but moves the "
                           "sliding-mode L",
    "phase delay spread, 1 °/s²": "the amplitude damping that gives 1 dB adds ≈ 4 samples of "
                                  "lag; the stiction variant keeps 24.4–29.3",
    "TF00": "a gain-only model with the study's own 24–31-sample lag fits ≤ 66 % on its 22 "
            "validation points (≤ 72 % as a mean of records, no compare reading reaches "
            "78.56); the input paired 12 samples later, noise kept, gives the study's three "
            "TF rows together, 78.77, 98.50, 94.41 % (bench/study_gaps.py --only cause; "
            "bench/study.py --tf-input-lag 12): the study's TF records were aligned apart from "
            "its FRF's",
}


@pytest.mark.slow
def test_every_study_row() -> None:
    """Every bench row (≈ 27 min CPU; the transfer-function section's 42 output-error fits
    ≈ 17 of it): within tolerance, or a known miss."""
    model = realistic_rig_model()
    rows = [row for section in bench.SECTIONS.values() for row in section(model, 7)]
    unexpected = [f"{r.name}: twin {r.twin}, study {r.study}" for r in rows
                  if not r.ok and not any(r.name.startswith(k) for k in KNOWN_MISSES)]
    assert not unexpected, "\n".join(unexpected)
    # 16 of 23 at seed 7 on the merged tree: 5 scale, 7 FRF, cross-axis, misalignment, 2 TF
    assert sum(r.ok for r in rows) >= 16
