"""A wrong mapping is named at its FILE:LINE:COLUMN, a damaged logger file by its name; both
exit 2 before anything is analysed (docs/interfaces.md §3, "Logger files")."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from logger_writers import write_mf4, write_tdms
from nptdms import ChannelObject, TdmsWriter
from recording_data import one_step_dataset, sine_step, step_logs
from typer.testing import CliRunner

from aatest.cli import app
from aatest.recording.dataset import Dataset

RUNNER = CliRunner()


def _dataset() -> tuple[Dataset, dict[str, object]]:
    """One synthetic sine step (NumPy only) and the dataset.yaml keys that describe it."""
    step = sine_step("s01", samples=4096)
    table, daq = step_logs(step, 3)
    return one_step_dataset("mapping-errors", step, table, daq)


@pytest.fixture
def tdms(tmp_path: Path) -> Path:
    """A TDMS file by npTDMS (plus a text channel in the table group) and its mapping."""
    dataset, manifest = _dataset()
    mapping = write_tdms(dataset, manifest, tmp_path / "tdms")
    with TdmsWriter(str(mapping.parent / "logger.tdms"), mode="a") as writer:
        writer.write_segment([ChannelObject("Step 1 Table", "Operator",
                                            np.array(["A. Lab"] * 4))])
    return mapping


def _analyse(target: Path) -> tuple[int, str]:
    done = RUNNER.invoke(app, ["analyze", str(target)])
    assert done.exception is None or isinstance(done.exception, SystemExit), done.output
    return done.exit_code, done.output


def _position(text: str, needle: str, key: str) -> tuple[int, int]:
    """1-based line and column of ``key`` on the line holding ``needle``."""
    for number, line in enumerate(text.splitlines(), start=1):
        if needle in line:
            return number, line.index(key) + 1
    raise AssertionError(f"{needle!r} not in the mapping")


def _edit(mapping: Path, old: str, new: str, count: int = 1) -> str:
    text = mapping.read_text(encoding="utf-8")
    assert text.count(old) >= count, old
    text = text.replace(old, new, count)
    mapping.write_text(text, encoding="utf-8")
    return text


def test_the_unedited_mapping_is_accepted(tdms: Path) -> None:
    """The baseline of the cases below: the same file and mapping analyse (exit 0)."""
    code, output = _analyse(tdms)
    assert code == 0, output


@pytest.mark.parametrize(("old", "new", "needle", "key", "says"), [
    # unknown channel: located at the mapping entry, naming the file and group
    ("channel: Rate\n", "channel: Rates\n", "channel: Rates", "channel",
     "no channel 'Rates' of group 'Step 1 Table'"),
    # missing group
    ("table: Step 1 Table", "table: Step 9 Table", "table: Step 9 Table", "table",
     "no group 'Step 9 Table'"),
    # a unit aatest does not know for the quantity
    ("unit: rad/s^2", "unit: furlong/s^2", "furlong", "unit", "Input should be"),
    # a wrong type in the mapping
    ("unit: mV\n", "unit: mV\n      gain: lots\n", "gain: lots", "gain",
     "valid number"),
    # the file states radians, the mapping says degrees (no scaling between them)
    ("channel: Position\n    unit: rad", "channel: Position\n    unit: arcsec", "unit: arcsec",
     "unit", "is in 'rad' by the file, the mapping says 'arcsec'"),
    # a text channel where a number is needed
    ("channel: Acceleration\n", "channel: Operator\n", "channel: Operator", "channel",
     "holds object values, not numbers"),
])
def test_a_wrong_mapping_is_located(tdms: Path, old: str, new: str, needle: str, key: str,
                                    says: str) -> None:
    text = _edit(tdms, old, new)
    line, column = _position(text, needle, key)
    code, output = _analyse(tdms)
    assert code == 2, output
    located = [row for row in output.splitlines() if f"{tdms}:{line}:{column}:" in row]
    assert located and says in located[0], output
    assert not (tdms.parent / "results.json").exists()


def test_every_problem_is_reported_at_once(tdms: Path) -> None:
    _edit(tdms, "channel: Rate\n", "channel: Rates\n")
    _edit(tdms, "channel: FPLatch", "channel: Latch")
    code, output = _analyse(tdms)
    assert code == 2
    assert "no channel 'Rates'" in output and "no channel 'Latch'" in output


def test_an_optional_channel_may_be_absent(tdms: Path) -> None:
    """``required: false``: the channel is filled as the CSV importer fills it."""
    _edit(tdms, "channel: FPLatch\n", "channel: Latch\n    required: false\n")
    code, output = _analyse(tdms)
    assert code == 0, output


def test_an_analogue_pulse_without_threshold_names_the_file(tdms: Path) -> None:
    _edit(tdms, "    threshold: 2.5\n", "")
    code, output = _analyse(tdms)
    assert code == 2, output
    assert "logger.tdms" in output and "must be 0 or 1, found 5.0" in output


@pytest.mark.parametrize("keep", [0.67, 0.999])
def test_a_truncated_tdms_file_is_named(tdms: Path, keep: float) -> None:
    data_file = tdms.parent / "logger.tdms"
    data = data_file.read_bytes()
    data_file.write_bytes(data[: int(len(data) * keep)])
    code, output = _analyse(tdms)
    assert code == 2, output
    assert f"{data_file}: truncated or damaged TDMS file" in output


def test_a_file_that_is_not_tdms_is_named(tdms: Path) -> None:
    data_file = tdms.parent / "logger.tdms"
    data_file.write_bytes(b"PK\x03\x04 a zip file, not a TDMS file")
    code, output = _analyse(tdms)
    assert code == 2
    assert f"{data_file}: not a TDMS file" in output


@pytest.mark.parametrize("keep", [0.5, 0.99])
def test_a_truncated_mf4_file_is_named(tmp_path: Path, keep: float) -> None:
    dataset, manifest = _dataset()
    mapping = write_mf4(dataset, manifest, tmp_path / "mf4")
    data_file = mapping.parent / "step1.mf4"
    data = data_file.read_bytes()
    data_file.write_bytes(data[: int(len(data) * keep)])
    code, output = _analyse(mapping)
    assert code == 2, output
    assert f"{data_file}: corrupt or unreadable MF4 file" in output
    assert "Exception ignored" not in output


def test_a_missing_mf4_group_index_is_located(tmp_path: Path) -> None:
    dataset, manifest = _dataset()
    mapping = write_mf4(dataset, manifest, tmp_path / "mf4")
    text = _edit(mapping, "daq: 1\n", "daq: 7\n")
    line, column = _position(text, "daq: 7", "daq")
    code, output = _analyse(mapping)
    assert code == 2
    assert f"{mapping}:{line}:{column}: steps.0.daq: no group 7" in output


def test_an_mf4_group_name_given_twice_is_located(tmp_path: Path) -> None:
    """asammdf lets two channel groups share an acquisition name: the mapping must say which."""
    dataset, manifest = _dataset()
    mapping = write_mf4(dataset, manifest, tmp_path / "mf4", acq_name="Logger")
    data_file = mapping.parent / "step1.mf4"
    text = _edit(mapping, "daq: 1\n", "daq: Logger\n")
    line, column = _position(text, "daq: Logger", "daq")
    code, output = _analyse(mapping)
    assert code == 2, output
    assert f"{mapping}:{line}:{column}: steps.0.daq: 2 channel groups of {data_file} are " \
        "named 'Logger' (indices [0, 1])" in output
