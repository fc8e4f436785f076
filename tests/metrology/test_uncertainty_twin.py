"""Slow: the scale-factor uncertainty against repeated calibrations on the digital twin.

Eight seeds of the shipped scale-factor procedure give eight independent estimates of K; their
spread is what changes from run to run, so it must match the budget's Type A part (the Type B rows —
logger gain, encoder, temperature — are the same on every seed of one rig; 8 samples estimate a
standard deviation only to about ±25 %, hence the wide acceptance band). The Type B rows are
proven by ``tests/coverage`` on rigs whose instrument errors are drawn). The seed also redraws
the table's motor band, which dithers the sensor's hysteresis differently in every run — a
run-to-run effect a one-record procedure cannot evaluate (its repeatability row says so): the
measured ratio is 1.50, hence the band up to 2.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from aatest.engine.run.session import run
from aatest.metrology.uncertainty.gum import evaluate
from aatest.metrology.uncertainty.measurands import RigConstants, scale_factor_measurand

PROCEDURE = Path(__file__).resolve().parents[2] / "src/aatest/procedures/scale-factor.yaml"


@pytest.mark.slow
def test_twin_spread_of_k_is_covered_by_u_c(tmp_path: Path) -> None:
    estimates, u_c = [], []
    for seed in range(1, 9):
        _, results = run(PROCEDURE, None, tmp_path / f"s{seed}", False, seed, None,
                         show_progress=False)
        measurand = scale_factor_measurand(results, "v_sz", RigConstants())
        assert measurand is not None
        gum = evaluate(measurand)
        estimates.append(gum.value)
        u_c.append(float(np.sqrt(sum(r.contribution**2 for r in gum.rows if r.type == "A"))))
    spread = float(np.std(estimates, ddof=1))
    ratio = spread / float(np.mean(u_c))
    assert 0.4 < ratio < 2.0, f"twin spread {spread:.3g} vs u_c {np.mean(u_c):.3g}"
