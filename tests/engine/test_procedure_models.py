"""Procedure models: defaults, strictness, one key per step, frozen."""

from __future__ import annotations

import pytest
from pydantic import ValidationError

from aatest.engine.procedure.models import Procedure, SineStep, SweepFrequencies

BASE = {"procedure": "p", "sensor": {"model": "sr207"}}


def _proc(*steps: dict, **top: object) -> Procedure:
    return Procedure.model_validate({**BASE, "steps": list(steps), **top})


def test_defaults_follow_the_contract() -> None:
    proc = _proc({"static": None})
    assert (proc.rig.turntable, proc.rig.daq, proc.rig.chamber) == ("sim", "sim", "none")
    assert (proc.sampling.rate_hz, proc.sampling.samples, proc.sampling.settle_s) == (
        2000.0, 131072, 5.0)
    assert proc.report.template == "calibration-certificate" and proc.report.sign is False
    assert proc.steps[0].kind == "static" and proc.sensor.serial == "unknown"


@pytest.mark.parametrize("bad", [
    {"sampling": {"rate_hz": "2000"}},
    {"sampling": {"samples": 1.5}},
    {"report": {"sign": "yes"}},
    {"sampling": {"rate_hz": float("inf")}},
    {"sampling": {"rate_hz": -1.0}},
], ids=["str-number", "float-samples", "str-bool", "inf", "negative"])
def test_scalars_are_strict(bad: dict) -> None:
    with pytest.raises(ValidationError):
        _proc({"static": {}}, **bad)


def test_numeric_serial_is_read_as_text() -> None:
    assert _proc({"static": {}}, sensor={"model": "m", "serial": 1234}).sensor.serial == "1234"


def test_sine_needs_one_frequency_and_one_size() -> None:
    with pytest.raises(ValidationError, match="exactly one of frequency_hz or cycles"):
        SineStep(accel_dps2=1.0)
    with pytest.raises(ValidationError, match="exactly one of accel_dps2 or amplitude_deg"):
        SineStep(frequency_hz=1.0, accel_dps2=1.0, amplitude_deg=1.0)


def test_sweep_grid_rules() -> None:
    with pytest.raises(ValidationError, match="start_hz, ratio and stop_hz together"):
        SweepFrequencies(start_hz=0.4, ratio=1.2)
    with pytest.raises(ValidationError, match="explicit cycles imply snap: coherent"):
        SweepFrequencies(cycles=(1, 2), snap="none")
    with pytest.raises(ValidationError):
        SweepFrequencies(start_hz=0.4, ratio=1.0, stop_hz=10)  # ratio must exceed 1


def test_samples_and_duration_are_exclusive() -> None:
    with pytest.raises(ValidationError, match="either samples or duration_s"):
        _proc({"static": {"samples": 10, "duration_s": 1.0}})


def test_models_are_frozen() -> None:
    proc = _proc({"static": {}})
    with pytest.raises(ValidationError):
        proc.procedure = "other"  # type: ignore[misc]
