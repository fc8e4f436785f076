"""The example vendor MEMS sensor calibrates against its own datasheet, not SR-207 numbers."""

from __future__ import annotations

from pathlib import Path

import pytest

from aatest.engine.run.session import run

PROCEDURE = """\
procedure: vendor-scale-factor
sensor: {model: acme-mems-aa, serial: "M-7"}
rig: {turntable: acme-single-axis, daq: sim, chamber: none}
sampling: {rate_hz: 2000, samples: 16000, settle_s: 1}
steps:
  - sine: {axis: inner, frequency_hz: 2.0, accel_dps2: 1200, snap: coherent}
  - sine: {axis: inner, frequency_hz: 0.5, accel_dps2: 100, snap: coherent}
analysis: [sync, reference, scale_factor]
report: {template: calibration-certificate, sign: false}
"""


@pytest.mark.usefixtures("vendor_example")
def test_vendor_sensor_calibration_recovers_the_twins_truth(tmp_path: Path,
                                                            monkeypatch: pytest.MonkeyPatch
                                                            ) -> None:
    monkeypatch.setenv("AATEST_RECORDS", f"sqlite:///{tmp_path / 'records.db'}")
    path = tmp_path / "vendor.yaml"
    path.write_text(PROCEDURE)
    _, results = run(path, None, tmp_path / "run", False, 0, None, show_progress=False,
                     confirm_prompts="auto")
    sf = results.analysis.scale_factor["v_sz"]
    # the 2 Hz, 1200 °/s² step calibrates (the 0.5 Hz one is the smaller acceleration)
    assert sf.steps == ["s001-sine-inner-2.0000Hz-1200dps2"]
    from aatest_vendor_example.sensor import MemsAngularAccelerometer

    from aatest.twin.api import realistic_rig_model
    from aatest.twin.truth import scale_factor_truth_v_per_dps2

    model = realistic_rig_model(MemsAngularAccelerometer().datasheet())
    truth = scale_factor_truth_v_per_dps2(model, "v_sz", 2.0, 1200.0, model.chamber.ambient_c)
    assert sf.expanded_uncertainty is not None
    assert abs(sf.scale_v_per_dps2 - truth) <= sf.expanded_uncertainty, (sf.scale_v_per_dps2,
                                                                         truth)
    assert sf.scale_v_per_dps2 == pytest.approx(0.001, rel=0.02)  # the datasheet's ±2 %
    assert sf.order < 15
