"""Reference corrections: the schema, and the inverse applied to the logs as they are read."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from aatest.batch.correction import ReferenceCorrection, _Undo, load_correction
from aatest.engine.errors import InputError
from aatest.engine.logs import SampledLog


def _fix(**errors: object) -> ReferenceCorrection:
    return ReferenceCorrection.model_validate(
        {"reference": "R", "found_on": "2026-11-20", "reason": "found", **errors})


def test_an_encoder_scale_error_is_undone_on_every_encoder_channel() -> None:
    rng = np.random.default_rng(7)
    angle = rng.normal(size=50)
    table = SampledLog("table", 1000.0, np.arange(50) / 1000.0,
                       {"inner_position_deg": np.round(angle / 1e-4) * 1e-4 * 1.0005,
                        "inner_accel_dps2": angle * 1.0005, "sync_pulse": np.ones(50)},
                       quantisation={"inner_position_deg": (1.0005e-4, 0.0)})
    fixed = _Undo(_fix(encoder_scale_error_ppm=500)).log(table)
    # a division by 1.0005: exact to a few ulp
    np.testing.assert_allclose(fixed["inner_accel_dps2"], angle, rtol=1e-15)
    np.testing.assert_array_equal(fixed["sync_pulse"], table["sync_pulse"])
    quantum, offset = fixed.quantisation["inner_position_deg"]
    assert quantum == pytest.approx(1e-4, rel=1e-15) and offset == 0.0
    codes = fixed["inner_position_deg"] / quantum
    np.testing.assert_allclose(codes, np.round(codes), atol=1e-9)  # still integer codes


def test_a_logger_error_is_undone_on_the_named_channels_only() -> None:
    volts = np.linspace(-1.0, 1.0, 11)
    daq = SampledLog("daq", 1000.0, np.arange(11) / 1000.0,
                     {"v_sz": 1.002 * volts + 0.01, "v_sy": volts, "trigger": np.zeros(11)})
    fixed = _Undo(_fix(logger_gain_error_ppm=2000, logger_offset_v=0.01,
                       channels=["v_sz"])).log(daq)
    np.testing.assert_allclose(fixed["v_sz"], volts, atol=1e-15)
    np.testing.assert_array_equal(fixed["v_sy"], volts)
    every = _Undo(_fix(logger_gain_error_ppm=2000)).log(daq)
    np.testing.assert_allclose(every["v_sy"], volts / 1.002, rtol=1e-15)
    np.testing.assert_array_equal(every["trigger"], daq["trigger"])


def test_the_schema_demands_an_error_and_fits_the_reference_kind(tmp_path) -> None:
    with pytest.raises(ValidationError, match="state at least one"):
        _fix()
    assert _fix(encoder_scale_error_ppm=5).fits_kind("encoder") is None
    encoder_fix = _fix(encoder_scale_error_ppm=5)
    assert "is of kind data-logger" in (encoder_fix.fits_kind("data-logger") or "")
    assert "is of kind encoder" in (_fix(logger_gain_error_ppm=5).fits_kind("encoder") or "")
    path = tmp_path / "c.yaml"
    path.write_text("reference: R\nfound_on: 2026-11-20\nreason: r\nscale: 3\n",
                    encoding="utf-8")
    with pytest.raises(InputError, match=rf"{path}:4:1: scale: Extra inputs"):
        load_correction(path)
