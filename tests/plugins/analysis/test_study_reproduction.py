"""The study's scale-factor results (docs/method.md §4.3) reproduced on the twin.

The study measured, at 1 Hz and 400 °/s² on a 2 kHz, 70 s record: against the table's own
acceleration estimate a 1st-order model, ≈250.0 (°/s²)/V, RMSE ≈29.8 °/s², R² ≈0.989; against
a sliding-mode (Levant) reference RMSE ≈14.5 °/s², R² ≈0.997. The reference, not the sensor,
limits the fit, so the RMSE is the reference's own noise.

The twin's realistic defaults carry a 0.1″ position-periodic ripple at 1 and 2 cycles/°
(:data:`aatest.twin.defaults.RIPPLE_AMPLITUDE_DEG`), which is real axis motion: at 1″ it would put
≈60 °/s² RMS of 60–130 Hz acceleration into every table-derived reference at the sine's 64 °/s
peak rate (the sensor's 30 Hz dynamics do not pass it), far above what the study's 29.8 °/s² RMSE
leaves room for (≲ 10 °/s² beside the estimator's ≈28 °/s²). The reproduction runs the realistic
defaults as they are, with the study's reference choices set through the procedure's analysis
options (the 3rd-order model of the sliding-mode case through ``orders``).
"""

from __future__ import annotations

from functools import cache
from pathlib import Path
from typing import Any

import pytest

from aatest.engine.analysis.passes import run_analysis
from aatest.engine.procedure.loader import parse_procedure
from aatest.engine.run.session import prepare
from aatest.recording.dataset import Dataset

HERE = Path(__file__).parent / "procedures"
#: the study's measured results (docs/method.md §4.3)
STUDY = {"table_estimate": {"order": 1, "slope": 250.0, "rmse_dps2": 29.8, "r2": 0.989},
         "sliding_mode": {"order": 3, "slope": 255.1, "rmse_dps2": 14.5, "r2": 0.997}}
TOLERANCE = 0.25


def _scale_factor_options(path: Path) -> dict[str, Any]:
    """The ``scale_factor`` options the study procedure states (its analysis entry)."""
    proc = parse_procedure(path.read_text(encoding="utf-8"), str(path))
    for entry in proc.analysis:
        if isinstance(entry, dict) and "scale_factor" in entry:
            options = entry["scale_factor"]
            return dict(options if isinstance(options, dict) else options.model_dump())
    raise AssertionError(f"{path} names no scale_factor options")


@cache
def _dataset(reference: str, ripple_scale: float, samples: int) -> tuple[Dataset, dict[str, Any]]:
    from aatest.twin.api import realistic_rig_model, simulate_dataset

    path = HERE / f"study-{reference}.yaml"
    plan = prepare(path, None).plan
    steps = [s.model_copy(update={"samples": samples}) if s.recorded else s for s in plan.steps]
    model = realistic_rig_model()
    axis = model.table.inner
    ripple = [r.model_copy(update={"amplitude_deg": r.amplitude_deg * ripple_scale})
              for r in axis.rate_ripple]
    inner = axis.model_copy(update={"rate_ripple": ripple})
    table = model.table.model_copy(update={"inner": inner})
    return simulate_dataset(model.model_copy(update={"table": table}), steps, seed=3), \
        _scale_factor_options(path)


def _fit(reference: str, ripple_scale: float, samples: int, **override: Any) -> dict[str, Any]:
    data, options = _dataset(reference, ripple_scale, samples)
    assert options["reference"] == reference
    out = run_analysis("scale_factor", data, {**options, **override}).result["v_sz"].model_dump()
    return {"order": out["order"], "slope": out["coefficients"][1],
            "rmse_dps2": out["rmse_dps2"], "r2": out["fit"]["r2"],
            "scale_v_per_dps2": out["scale_v_per_dps2"]}


def _within(value: float, target: float) -> bool:
    return abs(value / target - 1.0) <= TOLERANCE


@pytest.mark.slow
@pytest.mark.parametrize("reference", ["table_estimate", "sliding_mode"])
def test_study_results_reproduced_on_full_record(reference: str) -> None:
    got, study = _fit(reference, 1.0, 140_000), STUDY[reference]
    assert _within(got["slope"], study["slope"]), got
    assert _within(got["rmse_dps2"], study["rmse_dps2"]), got
    assert _within(got["r2"], study["r2"]), got
    assert 1.0 - got["r2"] == pytest.approx(1.0 - study["r2"], rel=0.6), got  # the stricter form
    if reference == "table_estimate":
        assert got["order"] == study["order"]


@pytest.mark.slow
def test_a_1_arcsec_ripple_dominates_the_table_references() -> None:
    """With a 1″ ripple (ten times the default) the table estimate's RMSE is far above the
    study's: the term that sets it; the slope (and so the scale factor) is unaffected."""
    got = _fit("table_estimate", 10.0, 140_000)
    assert got["rmse_dps2"] > 2.0 * STUDY["table_estimate"]["rmse_dps2"]
    assert _within(got["slope"], 250.0)


def test_study_reference_rmse_on_short_record() -> None:
    """20 cycles instead of 70: the reference's noise, hence the RMSE, does not depend on N."""
    te = _fit("table_estimate", 1.0, 40_000)
    sm = _fit("sliding_mode", 1.0, 40_000)
    assert te["order"] == 1
    assert _within(te["rmse_dps2"], 29.8) and _within(sm["rmse_dps2"], 14.5), (te, sm)
    assert te["scale_v_per_dps2"] == pytest.approx(sm["scale_v_per_dps2"], rel=2e-3)


def test_table_estimate_and_smoothed_differ() -> None:
    """The two references are what their names say: the raw controller estimate keeps its
    noise (the study's ≈29.8 °/s²), the smoothed one is low-passed (well under 1 °/s²)."""
    data, _ = _dataset("table_estimate", 1.0, 40_000)
    raw = run_analysis("scale_factor", data, {"reference": "table_estimate"}).result["v_sz"]
    smooth = run_analysis("scale_factor", data, {"reference": "smoothed"}).result["v_sz"]
    assert raw.rmse_dps2 > 20.0
    assert smooth.rmse_dps2 < 1.0


def test_study_results_reproduced_with_the_realistic_defaults() -> None:
    """§4.3 within 25 % on a 20 s record of the study's sine (the reference's noise, hence RMSE
    and R², does not depend on N): table estimate → 1st order chosen, ≈250 (°/s²)/V, RMSE
    ≈29.8 °/s², R² ≈0.989; sliding mode with the study's 3rd-order model → RMSE ≈14.5 °/s²,
    R² ≈0.997, linear term ≈255.1."""
    te = _fit("table_estimate", 1.0, 40_000)
    sm = _fit("sliding_mode", 1.0, 40_000, orders=(3, 3))
    assert te["order"] == 1 and sm["order"] == 3
    for got, study in ((te, STUDY["table_estimate"]), (sm, STUDY["sliding_mode"])):
        for key in ("slope", "rmse_dps2", "r2"):
            assert _within(got[key], study[key]), (key, got, study)
        # R² near 1 hides a factor: the unexplained share 1 − R² within 60 %
        assert 1.0 - got["r2"] == pytest.approx(1.0 - study["r2"], rel=0.6), (got, study)
