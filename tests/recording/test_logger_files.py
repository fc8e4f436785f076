"""TDMS and MF4 files analyse to the results of the same run's CSV export (docs/interfaces.md
§3, "Logger files"), whether written by npTDMS/asammdf themselves or by ``aatest export``."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from logger_writers import assert_close_tree, write_mf4, write_tdms
from ruamel.yaml import YAML
from typer.testing import CliRunner

from aatest.cli import app
from aatest.recording import read_dataset
from aatest.results import RunResults
from aatest.results.root import UnitRef

QUICK = Path(__file__).resolve().parents[1] / "data" / "procedures" / "quick-sine-3-steps.yaml"
RUNNER = CliRunner()
#: Relative tolerance between analyses of the same run read from different files. The files
#: store float64, so the channels the analyses read are bit-identical to the CSV export's
#: where no unit conversion is mapped, and within 2 ulp (≈ 4e-16 relative) where one is
#: (rad → °, mV → V, K → °C: one rounding when the test writes, one when aatest converts).
#: The analyses are least-squares fits and FFT ratios of 8192-sample records, conditioned
#: well enough that a 1e-15 relative change of the inputs moves the results by < 1e-12;
#: 1e-9 leaves margin for summation order and still fails on any real mistake (a unit
#: mix-up, a shifted sample or a lost segment changes results by > 1e-4).
RTOL = 1e-9
#: absolute floor for quantities that are zero in truth (phases, offsets): same reasoning
ATOL = 1e-12


def _invoke(*args: str) -> Any:
    done = RUNNER.invoke(app, list(args))
    assert done.exception is None or isinstance(done.exception, SystemExit), done.output
    return done


@pytest.fixture(scope="module")
def twin(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """A seeded three-sine twin run, its CSV export and the analysis of that export."""
    tmp = tmp_path_factory.mktemp("twin")
    run_dir, csv_dir = tmp / "run", tmp / "csv"
    assert _invoke("run", str(QUICK), "--out", str(run_dir), "--no-progress",
                   "--seed", "7").exit_code == 0
    assert _invoke("export", str(run_dir), "--csv", str(csv_dir)).exit_code == 0
    assert _invoke("analyze", str(csv_dir)).exit_code == 0
    manifest = YAML(typ="safe").load((csv_dir / "dataset.yaml").read_text(encoding="utf-8"))
    return {"run": run_dir, "csv": csv_dir, "manifest": manifest,
            "results": json.loads((csv_dir / "results.json").read_text())}


def assert_same_results(expected: dict[str, Any], got: dict[str, Any]) -> None:
    """Every analysis number and verdict agrees within RTOL/ATOL; everything else exactly."""
    for section in ("analysis", "analysis_errors", "verdicts", "overall"):
        assert_close_tree(expected[section], got[section], RTOL, ATOL)
    assert len(expected["analysis"]["frf"]["v_sz"]) == 3  # the comparison saw the data


def _analysed(data: Path) -> dict[str, Any]:
    done = _invoke("analyze", str(data))
    assert done.exit_code == 0, done.output
    target = data if data.is_dir() else data.parent
    return json.loads((target / "results.json").read_text())


def test_tdms_from_nptdms_writer_analyses_like_the_csv_export(twin: dict[str, Any],
                                                              tmp_path: Path) -> None:
    mapping = write_tdms(read_dataset(twin["run"]), twin["manifest"], tmp_path / "tdms")
    assert_same_results(twin["results"], _analysed(mapping.parent))


def test_mf4_from_asammdf_writer_analyses_like_the_csv_export(twin: dict[str, Any],
                                                              tmp_path: Path) -> None:
    mapping = write_mf4(read_dataset(twin["run"]), twin["manifest"], tmp_path / "mf4")
    assert_same_results(twin["results"], _analysed(mapping))  # the mapping file named


def test_library_files_read_back_the_recorded_channels(twin: dict[str, Any],
                                                       tmp_path: Path) -> None:
    """Channel by channel: what the mapping converts equals the recording within 2 ulp of
    the converted quantity, the rest bit for bit; channels the files lack are filled."""
    recorded = read_dataset(twin["run"])
    imported = read_dataset(write_tdms(recorded, twin["manifest"], tmp_path / "t"))
    assert imported.metadata["source_format"] == "aatest.import/tdms"
    assert imported.metadata["fp_latch_s_present"] is True
    for mine, theirs in zip(recorded.steps, imported.steps, strict=True):
        assert theirs.step == mine.step
        assert (theirs.table.time_s == mine.table.time_s).all()
        assert (theirs.daq.time_s == mine.daq.time_s).all()
        for log_mine, log_theirs in ((mine.table, theirs.table), (mine.daq, theirs.daq)):
            assert set(log_theirs.channels) == set(log_mine.channels)
            for name, values in log_mine.channels.items():
                # 2 ulp (2·2.2e-16 relative, twice: write and convert) of the largest number
                # the file stores for the channel (kelvin: the temperature + 273.15)
                stored = float(abs(values).max()) + (273.15 if name == "temperature_c" else 0)
                diff = abs(log_theirs[name].astype(float) - values.astype(float)).max()
                assert diff <= 4 * 2.3e-16 * stored, name


def test_export_tdms_then_analyze_gives_the_csv_results(twin: dict[str, Any],
                                                        tmp_path: Path) -> None:
    out = tmp_path / "tdms"
    assert _invoke("export", str(twin["run"]), "--tdms", str(out)).exit_code == 0
    assert sorted(p.name for p in out.iterdir()) == ["mapping.yaml", "recording.tdms"]
    assert_same_results(twin["results"], _analysed(out))


def test_export_mf4_then_analyze_gives_the_csv_results(twin: dict[str, Any],
                                                      tmp_path: Path) -> None:
    out = tmp_path / "mf4"
    assert _invoke("export", str(twin["run"]), "--mf4", str(out)).exit_code == 0
    assert_same_results(twin["results"], _analysed(out))


def test_export_needs_exactly_one_target(twin: dict[str, Any], tmp_path: Path) -> None:
    done = RUNNER.invoke(app, ["export", str(twin["run"]), "--tdms", str(tmp_path / "a"),
                               "--mf4", str(tmp_path / "b")])
    assert done.exit_code == 2
    assert "exactly one of --csv, --tdms, --mf4" in done.output


@pytest.mark.parametrize("form", ["--tdms", "--mf4"])
def test_an_exported_simulation_analyses_as_a_simulation(twin: dict[str, Any], tmp_path: Path,
                                                         form: str) -> None:
    """A twin run exported to a logger file and analysed again stays a simulation: its
    mapping names the simulated parts and the import keeps them, so the analysis is numbered
    and titled as a simulation, never as a calibration."""
    out = tmp_path / form.strip("-")
    assert _invoke("export", str(twin["run"]), form, str(out)).exit_code == 0
    results = _analysed(out)
    assert results["metadata"]["simulated_parts"] == ["daq:sim", "turntable:sim"]
    assert results["metadata"]["kind"] == "simulation"
    assert results["certificate_number"].startswith("SIM-")


@pytest.mark.parametrize("form", ["--csv", "--tdms", "--mf4"])
def test_an_exported_run_analyses_as_the_same_unit(twin: dict[str, Any], tmp_path: Path,
                                                  form: str) -> None:
    """The unit a run calibrated is the unit its exported data names: the files state it per
    channel (``sensors``), and the analysis of the import reports, numbers and registers that
    unit. Before, the results kept no ``sensors`` and no unit: the terminal said ``Unit —``
    and the records store filed the calibration under model 'unknown', serial 'unspecified'."""
    out = tmp_path / form.strip("-")
    assert _invoke("export", str(twin["run"]), form, str(out)).exit_code == 0
    records = f"sqlite:///{tmp_path / 'records.sqlite'}"
    done = _invoke("analyze", str(out), "--records", records)
    assert done.exit_code == 0, done.output
    assert "Unit             sr207 T0001" in done.output, done.output
    results = RunResults.model_validate_json((out / "results.json").read_text())
    assert [(s.channel, s.model, s.serial) for s in results.metadata.sensors] == [
        ("v_sz", "sr207", "T0001")]
    assert results.metadata.unit() == UnitRef(model="sr207", serial="T0001")
    listed = _invoke("records", "list", "--include-simulations", "--records", records)
    (row,) = [line for line in listed.output.splitlines() if "SIM-" in line]
    assert row.split()[3:5] == ["sr207", "T0001"], row
    report = (out / "report.html").read_text()  # the traceability table's sensor row
    assert '<td class="t">v_sz</td><td class="t">I</td><td class="t">sr207</td>' \
        '<td class="t">T0001</td>' in report
