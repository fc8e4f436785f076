"""The lab profile: its prefix numbers the certificates; a bad file is located bad input."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from aatest.cli import app
from aatest.engine.errors import InputError
from aatest.records.hook import registering
from aatest.records.lab import LabProfile, load_lab
from aatest.results import RunResults

PROCEDURE = Path(__file__).parents[2] / "src" / "aatest" / "procedures" / "scale-factor.yaml"


def test_default_profile_without_file_or_environment() -> None:
    assert load_lab() == LabProfile()


def test_profile_from_environment(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    lab = tmp_path / "lab.yaml"
    lab.write_text("name: Rotary Lab\ncertificate_prefix: RL\ncalibration_interval_months: 6\n")
    monkeypatch.setenv("AATEST_LAB", str(lab))
    assert load_lab() == LabProfile(name="Rotary Lab", certificate_prefix="RL",
                                    calibration_interval_months=6)


def test_bad_profile_names_file_line_and_field(tmp_path: Path) -> None:
    lab = tmp_path / "lab.yaml"
    lab.write_text("name: Rotary Lab\ncalibration_interval_months: 0\n")
    with pytest.raises(InputError, match=r"lab\.yaml:2:\d+: calibration_interval_months"):
        load_lab(lab)


def test_run_numbers_certificates_with_the_lab_prefix(tmp_path: Path, sqlite_url: str) -> None:
    lab = tmp_path / "lab.yaml"
    lab.write_text("name: Rotary Lab\ncertificate_prefix: RL\ncalibration_interval_months: 6\n")
    out = tmp_path / "run"
    result = CliRunner().invoke(app, ["run", str(PROCEDURE), "--out", str(out), "--no-progress",
                                      "--records", sqlite_url, "--lab", str(lab)])
    assert result.exit_code == 0, result.output
    number = json.loads((out / "results.json").read_text())["certificate_number"]
    # the twin is simulated: its own series, whatever the lab's prefix
    assert number.startswith("SIM-") and number.endswith("-000001")
    registrar_results = RunResults(procedure="imported")
    with registering(sqlite_url, load_lab(lab), "analyze") as registrar:
        registrar.before_signing(registrar_results)
        bundle = tmp_path / "imported" / "report.html"
        bundle.parent.mkdir()
        bundle.write_text("<html></html>")
        registrar.after_signing(registrar_results, bundle)
    number = str(registrar_results.certificate_number)
    assert number.startswith("RL-") and number.endswith("-000001")  # a calibration: lab series
    listing = CliRunner().invoke(app, ["records", "list", "--since", "2000-01-01",
                                       "--until", "2000-12-31", "--records", sqlite_url])
    assert listing.exit_code == 0 and listing.stdout.strip() == "no matching records"
    bad = CliRunner().invoke(app, ["records", "list", "--since", "yesterday",
                                   "--records", sqlite_url])
    assert bad.exit_code == 2 and "--since 'yesterday'" in bad.stderr


def test_no_lab_profile_takes_the_simulation_series(tmp_path: Path) -> None:
    lab = tmp_path / "lab.yaml"
    lab.write_text("name: Sneaky Lab\ncertificate_prefix: SIM\n")
    with pytest.raises(InputError, match=r"lab\.yaml:2:\d+: certificate_prefix.*simulations"):
        load_lab(lab)
