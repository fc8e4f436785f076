"""Physically impossible values in TDMS/MF4 logger files are refused as in CSV files.

The CSV import refuses ``1e300`` of position, rate, acceleration or volts at its file, line
and column (:mod:`aatest.recording.data.plausible`); a logger file has no lines, so its import
names the file, the group, the channel and the sample index instead (exit 2), and nothing is
analysed.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from logger_writers import write_mf4, write_tdms
from recording_data import one_step_dataset, sine_step, step_logs
from typer.testing import CliRunner

from aatest.cli import app
from aatest.engine.logs import SampledLog
from aatest.recording.dataset import Dataset, StepData

RUNNER = CliRunner()
#: the sample the corrupted value sits at (inside the second TDMS segment / MF4 extension)
BAD_SAMPLE = 3000


def _with(log: SampledLog, channel: str, value: float) -> SampledLog:
    """``log`` with ``channel`` at :data:`BAD_SAMPLE` replaced by ``value``."""
    values = np.array(log[channel], dtype=np.float64)
    values[BAD_SAMPLE] = value
    return dataclasses.replace(log, channels=dict(log.channels) | {channel: values})


def _dataset(source: str, channel: str, value: float) -> tuple[Dataset, dict[str, object]]:
    """One synthetic sine step with one impossible value, and its dataset.yaml keys."""
    step = sine_step("s01", samples=4096)
    table, daq = step_logs(step, 3)
    if source == "table":
        table = _with(table, channel, value)
    else:
        daq = _with(daq, channel, value)
    return one_step_dataset("plausible", step, table, daq)


@pytest.mark.parametrize(("writer", "source", "channel", "file_channel", "says"), [
    (write_tdms, "table", "inner_rate_dps", "Rate", "inner_rate_dps 1e+300 °/s"),
    (write_tdms, "table", "inner_position_deg", "Position", "inner_position_deg 1e+300 °"),
    (write_tdms, "daq", "v_sz", "AI0", "v_sz 1e+300 V"),
    (write_mf4, "table", "outer_accel_dps2", "OuterAcceleration",
     "outer_accel_dps2 -1e+300 °/s²"),
    (write_mf4, "daq", "v_sz", "AI0", "v_sz 1e+300 V"),
])
def test_an_impossible_logged_value_is_refused_at_its_sample(
        tmp_path: Path, writer: object, source: str, channel: str, file_channel: str,
        says: str) -> None:
    value = -1e300 if "accel" in channel else 1e300
    dataset, manifest = _dataset(source, channel, value)
    mapping = writer(dataset, manifest, tmp_path)  # type: ignore[operator]
    done = RUNNER.invoke(app, ["analyze", str(mapping)])
    assert done.exit_code == 2, done.output
    output = " ".join(done.output.split())
    data_file = "logger.tdms" if writer is write_tdms else "step1.mf4"
    assert f"{tmp_path / data_file}:" in output
    assert f"channel '{file_channel}'" in output
    assert f"{says} at sample {BAD_SAMPLE} is outside" in output
    assert not (tmp_path / "results.json").exists()


def test_the_same_files_without_the_value_analyse(tmp_path: Path) -> None:
    """The baseline: the writers' files of the same step, uncorrupted, analyse (exit 0)."""
    step = sine_step("s01", samples=4096)
    dataset, manifest = _dataset("table", "inner_rate_dps", 0.0)
    dataset = dataclasses.replace(dataset, steps=(StepData(step, *step_logs(step, 3)),))
    done = RUNNER.invoke(app, ["analyze", str(write_tdms(dataset, manifest, tmp_path))])
    assert done.exit_code == 0, done.output
