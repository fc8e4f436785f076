"""Export to the contract §3 import format: exact columns, and import(export(x)) == x."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from recording_data import run_meta, sine_step, step_logs
from ruamel.yaml import YAML

from aatest.engine.logs import SampledLog
from aatest.engine.steps import PlannedStep
from aatest.recording import RunRecorder, read_dataset
from aatest.recording.data.exporter import export_csv
from aatest.recording.dataset import Dataset, StepData


def recorded_dataset(run_dir: Path, steps: list[PlannedStep], latch: bool = True) -> Dataset:
    recorder = RunRecorder(run_dir)
    recorder.write_run_metadata(
        run_meta(steps) | {"analysis": ["sync", "frf"], "report_template": "frequency-response"})
    for seed, step in enumerate(steps):
        recorder.write_step(step, *step_logs(step, seed, latch))
    recorder.finalize()
    return read_dataset(run_dir)


def assert_same_channels(original: SampledLog, imported: SampledLog, rtol: float = 0.0) -> None:
    np.testing.assert_array_equal(imported.time_s, original.time_s)
    for name, values in original.channels.items():
        np.testing.assert_allclose(imported[name], values, rtol=rtol, atol=0, err_msg=name)


def header(path: Path) -> list[str]:
    return path.read_text().split("\n", 1)[0].split(",")


def test_export_writes_the_contract_layout(tmp_path: Path) -> None:
    dataset = recorded_dataset(tmp_path / "run", [sine_step("s01"), sine_step("s02", axis="outer")])
    out = export_csv(dataset, tmp_path / "csv")
    assert sorted(p.name for p in out.iterdir()) == [
        "dataset.yaml", "s01_daq.csv", "s01_table.csv", "s02_daq.csv", "s02_table.csv"]
    table = header(out / "s01_table.csv")
    assert table[:5] == ["time_s", "position_deg", "rate_dps", "accel_dps2", "sync_pulse"]
    assert {"outer_position_deg", "fp_latch_s"} <= set(table)
    assert header(out / "s01_daq.csv") == [
        "time_s", "sync_pulse", "trigger", "v_sz", "temperature_c"]
    assert "inner_position_deg" in header(out / "s02_table.csv")
    doc = YAML(typ="safe").load((out / "dataset.yaml").read_text())
    assert doc["sample_rate_hz"] == 2000.0
    assert doc["sensors"][0]["channel"] == "v_sz"
    step = doc["steps"][0]
    assert {k: step[k] for k in ("id", "kind", "axis", "table", "daq")} == {
        "id": "s01", "kind": "sine", "axis": "inner",
        "table": "s01_table.csv", "daq": "s01_daq.csv"}
    assert step["frequency_hz"] == dataset.steps[0].step.frequency_hz
    assert step["accel_dps2"] == 100.0


def test_import_of_export_is_bit_exact_for_float64(tmp_path: Path) -> None:
    dataset = recorded_dataset(tmp_path / "run", [sine_step("s01"), sine_step("s02", axis="outer")])
    again = read_dataset(export_csv(dataset, tmp_path / "csv"))
    assert again.procedure == dataset.procedure
    assert again.sensors == dataset.sensors
    assert again.sample_rate_hz == dataset.sample_rate_hz
    for mine, theirs in zip(dataset.steps, again.steps, strict=True):
        assert theirs.step == mine.step
        assert_same_channels(mine.table, theirs.table)
        assert_same_channels(mine.daq, theirs.daq)
    assert again.metadata["fp_latch_s_present"] is True
    assert again.metadata["analysis"] == ["sync", "frf"]
    assert again.metadata["report_template"] == "frequency-response"


def test_float32_daq_volts_round_trip_to_their_precision(tmp_path: Path) -> None:
    step = sine_step("s01")
    table, daq = step_logs(step, 5)
    volts32 = {k: (v.astype(np.float32) if k.startswith("v_") else v)
               for k, v in daq.channels.items()}
    daq32 = SampledLog(daq.source, daq.sample_rate_hz, daq.time_s, volts32, daq.units)
    dataset = Dataset("f32", 2000.0, recorded_dataset(tmp_path / "r", [step]).sensors,
                      (StepData(step, table, daq32),), tmp_path)
    again = read_dataset(export_csv(dataset, tmp_path / "csv"))
    imported = again.steps[0].daq["v_sz"]
    np.testing.assert_array_equal(imported.astype(np.float32), daq32["v_sz"])


def test_export_of_an_import_keeps_what_was_absent(tmp_path: Path) -> None:
    """Filled-in channels (no latch, no temperature) stay absent through a second export."""
    dataset = recorded_dataset(tmp_path / "run", [sine_step("s01")], latch=False)
    daq_csv = export_csv(dataset, tmp_path / "a") / "s01_daq.csv"
    rows = [r for r in daq_csv.read_text().split("\n") if r]
    assert rows[0].endswith(",temperature_c")
    daq_csv.write_text("\n".join(r.rsplit(",", 1)[0] for r in rows) + "\n")
    first = read_dataset(tmp_path / "a")
    assert first.metadata["temperature_present"] is False
    second = read_dataset(export_csv(first, tmp_path / "b"))
    assert "temperature_c" not in header(tmp_path / "b" / "s01_daq.csv")
    assert second.metadata["temperature_present"] is False
    assert second.metadata["fp_latch_s_present"] is False
    assert_same_channels(first.steps[0].daq, second.steps[0].daq)


def test_amplitude_only_sine_gets_its_peak_acceleration(tmp_path: Path) -> None:
    base = sine_step("s01")
    step = base.model_copy(update={"accel_dps2": None, "amplitude_deg": 0.2})
    table, daq = step_logs(base, 1)
    dataset = Dataset("amp", 2000.0, (), (StepData(step, table, daq),), tmp_path)
    out = export_csv(dataset, tmp_path / "csv")
    doc = YAML(typ="safe").load((out / "dataset.yaml").read_text())
    expected = 0.2 * (2 * math.pi * base.frequency_hz) ** 2
    assert doc["steps"][0]["accel_dps2"] == pytest.approx(expected, rel=1e-15)


def test_twin_dataset_survives_record_export_import(tmp_path: Path) -> None:
    """Data from the digital twin: recording bit-exact, CSV export bit-exact on float64."""
    from aatest.twin import api
    steps = [
        PlannedStep(id="sine", kind="sine", axis="inner", samples=8192, sample_rate_hz=2000.0,
                    duration_s=4.096, frequency_hz=2.0, cycles=8, accel_dps2=400.0,
                    amplitude_deg=400.0 / (4 * math.pi) ** 2),
        PlannedStep(id="static", kind="static", axis="none", samples=4096, sample_rate_hz=2000.0,
                    duration_s=2.048, outer_deg=90.0),
    ]
    twin = api.simulate_dataset(api.realistic_rig_model(), steps, seed=3)
    recorder = RunRecorder(tmp_path / "run")
    recorder.write_run_metadata({"procedure": "twin", "sensors": [vars(s) for s in twin.sensors]})
    for data in twin.steps:
        recorder.write_step(data.step, data.table, data.daq)
    recorder.finalize()
    recorded = read_dataset(tmp_path / "run")
    imported = read_dataset(export_csv(recorded, tmp_path / "csv"))
    assert imported.sensors == recorded.sensors == twin.sensors
    for original, rec, imp in zip(twin.steps, recorded.steps, imported.steps, strict=True):
        assert rec.step == imp.step == original.step
        for log in ("table", "daq"):
            assert_same_channels(getattr(original, log), getattr(rec, log))
            assert_same_channels(getattr(original, log), getattr(imp, log))
    from aatest.engine.analysis import passes as analyses

    on_recording = {k: v.model_dump()
                    for k, v in analyses.run_analyses(recorded, ["sync"]).values.items()}
    on_export = {k: v.model_dump()
                 for k, v in analyses.run_analyses(imported, ["sync"]).values.items()}
    assert "sync" in on_recording
    assert _without_timings(on_export) == _without_timings(on_recording)


def _without_timings(values: object) -> object:
    """Analysis results minus wall-clock timings (the only thing allowed to differ)."""
    if isinstance(values, dict):
        return {k: _without_timings(v) for k, v in values.items() if k != "runtime_s"}
    if isinstance(values, (list, tuple)):
        return [_without_timings(v) for v in values]
    return values
