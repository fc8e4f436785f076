"""Long static records with every static analysis (issue 26 item 1), end to end on the twin.

Two 3-minute static records (axis up, axis down) are longer than the table's log buffer
(230 000 samples = 115 s at 2 kHz): the DAQ streams them and the table logs its full-rate head
only. Physical truths checked: sync fits the clocks on the head and states that it spans
≈ 115/180 of the record; bias and noise are of the whole record (not the head) and match the
twin's truth within their U; both budgets carry the partial clock fit's row, with the value its
definition gives, and U is built from it.
"""

from __future__ import annotations

import json
import math
import textwrap
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy import signal
from typer.testing import CliRunner

from aatest.cli import app
from aatest.engine.datasheet import SensorDatasheet
from aatest.twin.daq import antialias_filter
from aatest.twin.defaults import realistic_rig_model
from aatest.twin.truth import bias_truth_v

PROCEDURE = textwrap.dedent("""\
    procedure: long-static-all-test
    sensor: {{model: sr207, serial: "T-1"}}
    rig: {{turntable: sim, daq: sim, chamber: none}}
    sampling: {{rate_hz: 2000, settle_s: 5}}
    steps:
      - static: {{label: up, inner_deg: 0, outer_deg: 0, duration_s: {s}, motor_on: false}}
      - static: {{label: down, inner_deg: 0, outer_deg: 180, duration_s: {s}, motor_on: false}}
    analysis: [sync, bias, noise, drift]
    report: {{template: calibration-certificate, sign: false}}
    """)
#: the table's log buffer at 2 kHz, s (TableEnvelope.log_capacity_samples)
HEAD_S = 230_000 / 2000.0


def _run(tmp_path: Path, seconds: float) -> dict[str, Any]:
    procedure = tmp_path / "long.yaml"
    procedure.write_text(PROCEDURE.format(s=f"{seconds:g}"))
    runner = CliRunner()
    checked = runner.invoke(app, ["validate", str(procedure)])
    assert checked.exit_code == 0, checked.output
    out = tmp_path / "run"
    result = runner.invoke(app, ["run", str(procedure), "--out", str(out)])
    assert result.exit_code == 0, result.output
    analysis: dict[str, Any] = json.loads((out / "results.json").read_text())["analysis"]
    return analysis


def _within_u(entry: dict[str, Any], value: float, truth: float) -> None:
    assert abs(value - truth) <= entry["expanded_uncertainty"], (value, truth, entry["budget"])


def _row(entry: dict[str, Any], name: str) -> dict[str, Any]:
    rows = {row["name"]: row for row in entry["budget"]}
    assert name in rows, f"no {name} row in {sorted(rows)}"
    return rows[name]


def _u_from_rows(entry: dict[str, Any]) -> float:
    """k·√Σc² of the budget's contributions (the GUM law the stage applies)."""
    total = math.sqrt(sum(float(r["contribution"]) ** 2 for r in entry["budget"]))
    return float(entry["coverage_factor"]) * total


def _noise_truth_v(model: Any, band_hz: float, fs_hz: float = 2000.0) -> float:
    """The recorded output's RMS between DC and ``band_hz`` on the twin: the sensor's white
    noise (``noise_rms_v`` is its RMS behind the pre-sample filter) times the share of the
    filter's noise power in the band, and the converter's white quantisation noise q²/12 in
    the band's share of the Nyquist band."""
    b, a, _ = antialias_filter(float(model.daq.antialias_hz), 1.0 / fs_hz)
    f, h = signal.freqz(b, a, worN=2**16, fs=fs_hz)
    power, inband = np.abs(h) ** 2, f <= band_hz
    share = np.trapezoid(power[inband], f[inband]) / np.trapezoid(power, f)
    q_v = (model.daq.adc_range_v[1] - model.daq.adc_range_v[0]) / 2**model.daq.adc_bits
    sensor_v = model.sensors[0].noise_rms_v
    return math.sqrt(sensor_v**2 * share + q_v**2 / 12.0 * band_hz / (fs_hz / 2.0))


def _check(analysis: dict[str, Any], seconds: float) -> None:
    steps = analysis["sync"]["steps"]
    assert len(steps) == 2
    for entry in steps:
        # the head's edges span 115 s of a record of `seconds` + lead and stop lag
        assert entry["fit_coverage"] == pytest.approx(HEAD_S / seconds, rel=0.02)
        assert entry["extrapolation_u_s"] > 0.0
    model = realistic_rig_model(SensorDatasheet(model="sr207"))
    noise = analysis["noise"]["v_sz"]
    # the PSD and RMS are of the whole record, not of the head both loggers cover
    assert noise["record_s"] == pytest.approx(seconds, rel=1e-3)
    _within_u(noise, noise["rms_max_v"], _noise_truth_v(model, noise["band_hz"]))
    bias = analysis["bias"]["v_sz"]
    _within_u(bias, bias["bias_v"], bias_truth_v(model, "v_sz", 22.0))
    # the partial clock fit's row, as clock_window defines it, and U built from it
    u_off_ext = [math.sqrt(2 * e["offset_u_s"] ** 2 + e["extrapolation_u_s"] ** 2) for e in steps]
    sigma = noise["rms_v"]
    expected_bias = math.sqrt(sum((sigma * u / seconds) ** 2 for u in u_off_ext)) / 2
    expected_noise = max(sigma * u / (math.sqrt(2) * seconds) for u in u_off_ext)
    assert _row(bias, "clock_coverage")["standard_uncertainty"] == pytest.approx(
        expected_bias, rel=1e-6)  # the same formula; only the rounding of the inputs differs
    assert _row(noise, "clock_coverage")["standard_uncertainty"] == pytest.approx(
        expected_noise, rel=1e-6)
    for entry in (bias, noise):
        assert entry["expanded_uncertainty"] == pytest.approx(_u_from_rows(entry), rel=1e-6)
        assert "clock fit" in _row(entry, "clock_coverage")["basis"]


def test_three_minute_records_with_every_static_analysis(tmp_path: Path) -> None:
    analysis = _run(tmp_path, 180.0)
    _check(analysis, 180.0)
    drift = analysis["drift"]["v_sz"]
    assert drift["duration_s"] == pytest.approx(180.0, rel=0.01)


@pytest.mark.slow
def test_one_hour_records_with_every_static_analysis(tmp_path: Path) -> None:
    analysis = _run(tmp_path, 3600.0)
    _check(analysis, 3600.0)
    assert np.isfinite(analysis["drift"]["v_sz"]["drift_v_per_h"])
