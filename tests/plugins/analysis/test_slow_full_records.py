"""Full-length (2^17-sample) records on the twin: the published test conditions."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from analyse import analyse
from synthetic_rig import sine_step
from twin_helpers import twin_dataset

pytestmark = pytest.mark.slow
N = 2**17


def test_scale_factor_full_record(realistic_unit) -> None:  # type: ignore[no-untyped-def]
    model = realistic_unit.model_copy(update={"sensors": realistic_unit.sensors[:1]})
    data, truths = twin_dataset(model, [sine_step("cal", 66, 400.0, samples=N, settle_s=5.0)])
    v = analyse("scale_factor", data)["v_sz"]
    s = model.sensors[0]
    truth = s.scale_v_per_dps2 * (1 + s.scale_temperature.coefficient_per_c
                                  * (truths[0]["temperature_c"] - 25.0))
    assert v["scale_v_per_dps2"] == pytest.approx(truth, rel=1e-3)


def test_transfer_function_full_campaign_group(realistic_unit: Any) -> None:
    from test_tfest import F28

    model = realistic_unit.model_copy(update={"sensors": realistic_unit.sensors[:1]})
    steps = [sine_step(f"c{round(f * N / 2000)}", round(f * N / 2000), 100.0,
                       samples=N, settle_s=5.0) for f in F28]
    data, _ = twin_dataset(model, steps)
    v = analyse("transfer_function", data, antialias_hz=model.daq.antialias_hz)["v_sz"]
    assert v["fit_pct"] > 95.0 and v["zeros_outside_unit_circle"] == 0
    # realistic sensor: hysteresis/jerk terms bias the 2nd-order fit a little (30 Hz truth)
    assert v["second_order_delay"]["natural_frequency_hz"] == pytest.approx(30.0, rel=0.25)
    assert np.isfinite(v["nAIC"])
