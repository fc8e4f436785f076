"""A sensor logger that clips is found: each channel's samples at the rails of its input range.

Before anything moves, a plan whose nominal sensor output reaches the stated logger's rails is
refused (:mod:`aatest.preflight.logger_range`). A unit off nominal can still clip: the twin
runs one whose zero-g output is 2.9 V (the sr207's nominal is 2.5 V) through a 0…4.3 V logger,
and the samples at the rail are checked against the same unit logged, seed for seed, by a
±10 V logger that does not clip.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from aatest.cli import app
from aatest.engine.logs import DAQ, SampledLog
from aatest.engine.rig_description import LoggerSpec
from aatest.metrology.logger_rails import (
    DEFAULT_SOURCE,
    clipped_channels,
    converter_of,
    rail_tolerance_v,
    samples_at_rails,
)
from aatest.recording import extremes, read_dataset
from aatest.results import RunResults
from aatest.results.root import ChannelExtremes
from aatest.results.sensor import REFERENCE_BIAS_V, REFERENCE_SCALE_V_PER_DPS2, SensorInfo

RUNNER = CliRunner()
#: the logger of the clipping run: its top rail 4 V sits below the sr207's 2.5 V + 1.6 V peak
CLIPPING = LoggerSpec(bits=16, range_v=(0.0, 4.0))
FREQUENCY_HZ, ACCEL_DPS2, SAMPLES = 1.0, 400.0, 20000
PROCEDURE = f"""\
procedure: clipping-check
sensor: {{model: sr207, serial: "A1234"}}
rig: {{turntable: sim, daq: sim, chamber: none}}
sampling: {{rate_hz: 2000, samples: {SAMPLES}, settle_s: 2}}
steps:
  - sine: {{axis: inner, frequency_hz: {FREQUENCY_HZ}, accel_dps2: {ACCEL_DPS2}, snap: coherent}}
analysis: [sync, reference, scale_factor]
acceptance: {{judge: [scale_factor_deviation_pct]}}
report: {{template: calibration-certificate, sign: false}}
"""
#: a unit 0.4 V above its nominal zero-g output (2.9 + 1.6 V peaks) and the logger it is
#: recorded with: the twin's model file states the converter, the rig description the same
UNIT = """\
sensors:
  - {{channel: v_sz, axis: I, bias_v: 2.9}}
daq: {{adc_bits: 16, adc_range_v: [{low}, {high}]}}
"""
RIG = """\
turntable: {{plugin: sim}}
daq: {{plugin: sim, model: "{unit}"}}
instruments:
  logger: {{bits: 16, range_v: [{low}, {high}]}}
"""
#: the top rail of the clipping logger, V: above the nominal unit's 4.106 V peak, below this one's
TOP_V = 4.3


def _files(tmp: Path, low: float, high: float) -> Path:
    (tmp / "p.yaml").write_text(PROCEDURE, encoding="utf-8")
    (tmp / "unit.yaml").write_text(UNIT.format(low=low, high=high), encoding="utf-8")
    (tmp / "rig.yaml").write_text(RIG.format(low=low, high=high, unit=tmp / "unit.yaml"),
                                  encoding="utf-8")
    return tmp / "rig.yaml"


def _run(tmp: Path, rig: Path | None) -> tuple[int, dict, Path]:
    (tmp / "p.yaml").write_text(PROCEDURE, encoding="utf-8")
    args = ["run", str(tmp / "p.yaml"), "--out", str(tmp / "run"), "--no-progress",
            "--seed", "5", "--records", f"sqlite:///{tmp / 'records.db'}"]
    done = RUNNER.invoke(app, args + (["--rig", str(rig)] if rig is not None else []))
    assert done.exception is None or isinstance(done.exception, SystemExit), done.output
    return done.exit_code, json.loads((tmp / "run" / "results.json").read_text()), tmp / "run"


def test_extremes_count_the_samples_at_each_and_leave_nan_out() -> None:
    values = np.array([1.0, np.nan, 3.0, 3.0, -2.0, 3.0, -2.0, np.nan])
    assert extremes.of_values(values) == [-2.0, 2, 3.0, 3]
    low, n_low, high, n_high = extremes.of_values(np.array([np.nan, np.nan]))
    assert math.isnan(low) and math.isnan(high) and n_low == n_high == 0
    assert extremes.of_values(np.array([]))[1::2] == [0, 0]


def test_extremes_of_pieces_merge_to_those_of_the_whole() -> None:
    """A streamed record notes its extremes piece by piece: the same as of the whole."""
    rng = np.random.default_rng(11)
    values = np.clip(rng.normal(0.0, 1.0, 10_000), -1.5, 1.5)  # many samples at each extreme
    values[rng.integers(0, values.size, 40)] = np.nan
    pieces = np.split(values, [1, 1000, 1001, 6000])
    found: dict[str, extremes.Extremes] = {}
    for piece in pieces:
        log = SampledLog(DAQ, 2000.0, np.arange(piece.size) / 2000.0, {"v_sz": piece})
        found = extremes.merged_logs(found, extremes.of_log(log))
    whole = extremes.of_values(values)
    assert found == {"v_sz": whole}
    assert whole[0] == -1.5 and whole[2] == 1.5 and whole[1] > 100 and whole[3] > 100


def test_a_rail_is_within_one_step_and_the_stated_accuracy() -> None:
    q = CLIPPING.step_v
    top_tolerance_v = q + CLIPPING.offset_accuracy_v + CLIPPING.gain_accuracy_pct / 100 * 4.0
    # a sum of three positive terms rounds to within a few ulp whatever the order; 1e-9 still
    # fails on any term left out (the smallest, q = 61 µV, is 1.2 % of the 5.06 mV sum)
    assert rail_tolerance_v(CLIPPING, 4.0) == pytest.approx(top_tolerance_v, rel=1e-9)
    at_top = ChannelExtremes(least_v=1.0, samples_at_least=1, largest_v=4.0 - q,
                             samples_at_largest=300)
    assert samples_at_rails(at_top, CLIPPING) == 300
    both = at_top.model_copy(update={"least_v": 0.0, "samples_at_least": 7})
    assert samples_at_rails(both, CLIPPING) == 307
    inside = at_top.model_copy(update={"largest_v": 4.0 - 1.01 * top_tolerance_v})
    assert samples_at_rails(inside, CLIPPING) == 0


def test_only_a_stated_or_simulated_logger_is_judged() -> None:
    """A real logger nobody stated gets no rail verdict: its range is unknown."""
    step = {"id": "s1", "kind": "sine",
            "daq_extremes": {"v_sz": [0.5, 1, 9.99969482421875, 40]}}  # 10 V − q: the top rail
    sensors = [SensorInfo(channel="v_sz", axis="I").model_dump()]

    def judged(metadata: dict) -> dict[str, int]:
        results = RunResults.model_validate(
            {"procedure": "p", "steps": [step], "metadata": {"sensors": sensors, **metadata}})
        return clipped_channels(results, ["v_sz"])

    assert converter_of({})[1] == DEFAULT_SOURCE
    assert judged({}) == {}  # a real logger, range not stated
    assert judged({"simulated_parts": ["daq:sim"]}) == {"v_sz": 40}  # the twin's ±10 V
    own = {"plugin": "sim", "model": "unit.yaml"}  # the twin with a model file: its own logger
    assert judged({"simulated_parts": ["daq:sim"], "rig": {"daq": own}}) == {}
    def stated(range_v: list[float]) -> dict:
        return {"rig": {"instruments": {"logger": {"range_v": range_v}}}}

    assert judged(stated([-20, 20])) == {"v_sz": 0}  # 9.9997 V is far inside ±20 V
    assert judged(stated([0, 10])) == {"v_sz": 40}
    # beyond a stated rail is at it: the logger cannot have logged more than its range
    assert judged(stated([-5, 5])) == {"v_sz": 40}


def test_a_clipping_logger_fails_the_run_with_its_samples_at_the_rail(tmp_path: Path) -> None:
    (tmp_path / "clip").mkdir()
    code, results, run_dir = _run(tmp_path / "clip", _files(tmp_path / "clip", 0.0, TOP_V))
    assert code == 1
    rails = [v for v in results["verdicts"] if v["quantity"] == "samples_at_logger_rails"]
    assert [(v["channel"], v["verdict"], v["limit_source"]) for v in rails] == [
        ("v_sz", "fail", "logger")]
    q = TOP_V / 2**16
    # every sample at the rail is one the recording holds at its top code, 4.3 V − q
    volts = read_dataset(run_dir).steps[0].daq.channels["v_sz"]
    assert rails[0]["value"] == np.count_nonzero(volts >= TOP_V - q) > 0.1 * SAMPLES
    # the physics: the same unit and seed logged by a ±10 V logger goes above the rail's
    # rounding boundary (4.3 V − 1.5 q) in as many samples, within one sample at each of the
    # 20 crossings of the 10 periods (the two loggers round differently near the boundary)
    (tmp_path / "wide").mkdir()
    code, _, wide_dir = _run(tmp_path / "wide", _files(tmp_path / "wide", -10.0, 10.0))
    assert code == 0
    wide = read_dataset(wide_dir).steps[0].daq.channels["v_sz"]
    above = int(np.count_nonzero(wide >= TOP_V - 1.5 * q))
    assert abs(rails[0]["value"] - above) <= 2 * FREQUENCY_HZ * SAMPLES / 2000.0
    certificate = (run_dir / "report.html").read_text(encoding="utf-8")
    assert "Samples at the logger&#39;s input-range limits" in certificate
    assert "the logger clipped the output" in certificate


def test_a_plan_the_nominal_unit_would_clip_is_refused_before_anything_moves(tmp_path: Path
                                                                            ) -> None:
    """The nominal sr207 peaks at 2.5 + 0.004014 × 400 = 4.106 V: a 0…4 V logger refuses the
    step at its place in the procedure, in ``validate`` and before ``run`` records anything."""
    rig = _files(tmp_path, 0.0, 4.0)
    checked = RUNNER.invoke(app, ["validate", str(tmp_path / "p.yaml"), "--rig", str(rig)])
    assert checked.exit_code == 2
    assert "p.yaml:6:5: steps.0.sine: step" in checked.output  # the sine entry
    assert "puts out 0.894…4.11 V" in checked.output and "0…4 V" in checked.output
    done = RUNNER.invoke(app, ["run", str(tmp_path / "p.yaml"), "--rig", str(rig), "--out",
                               str(tmp_path / "run"), "--no-progress"])
    assert done.exit_code == 2 and not (tmp_path / "run").exists()
    ok = RUNNER.invoke(app, ["validate", str(tmp_path / "p.yaml"), "--rig",
                             str(_files(tmp_path, 0.0, TOP_V))])
    assert ok.exit_code == 0, ok.output


def test_a_logger_with_headroom_passes_with_no_sample_at_a_rail(tmp_path: Path) -> None:
    code, results, _ = _run(tmp_path, None)  # the twin's ±10 V logger
    assert code == 0 and results["overall"] == "pass"
    rails = [v for v in results["verdicts"] if v["quantity"] == "samples_at_logger_rails"]
    assert [(v["channel"], v["value"], v["verdict"]) for v in rails] == [("v_sz", 0.0, "pass")]
    noted = results["steps"][0]["daq_extremes"]["v_sz"]
    swing_v = REFERENCE_SCALE_V_PER_DPS2 * ACCEL_DPS2
    assert noted["largest_v"] == pytest.approx(REFERENCE_BIAS_V + swing_v, abs=0.05)
    assert noted["least_v"] == pytest.approx(REFERENCE_BIAS_V - swing_v, abs=0.05)
