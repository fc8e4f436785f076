"""``aatest export`` keeps the rig description's instruments (docs/interfaces.md §3).

Without them an analysis or ``diagnose`` of the export falls back to the stated default
logger (±10 V, 16 bit) and default encoder, not the rig's stated ones.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import pytest
from ruamel.yaml import YAML

from aatest.diagnose.logger_chain import stated_converter
from aatest.engine.errors import InputError
from aatest.engine.rig_description import Instruments
from aatest.engine.run.session import run
from aatest.metrology.uncertainty import components as comp
from aatest.metrology.uncertainty.measurands import RigConstants
from aatest.recording import read_dataset
from aatest.recording.data.exporter import export_csv
from aatest.recording.data.logger_export import export_tdms
from aatest.results import RunResults

QUICK = Path(__file__).resolve().parents[1] / "data" / "procedures"

#: a 12-bit ±5 V logger, unlike the stated default (16 bit, ±10 V), so a fallback shows
RIG_YAML = """\
turntable: {plugin: sim}
instruments:
  encoder: {accuracy_arcsec: 1.5, cert_id: ENC-77, cert_date: 2026-01-12, lab: PTB}
  logger: {bits: 12, range_v: [-5.0, 5.0], offset_accuracy_v: 0.0015, cert_id: LOG-123}
"""


@pytest.fixture(scope="module")
def twin_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A twin run of the quick two-step static procedure with a stated rig description."""
    base = tmp_path_factory.mktemp("instruments")
    rig = base / "rig.yaml"
    rig.write_text(RIG_YAML, encoding="utf-8")
    out, _ = run(QUICK / "quick-static-2-steps.yaml", rig, base / "run", False, 3, None,
                 show_progress=False, confirm_prompts="auto")
    return Path(str(out))


def test_export_import_round_trips_the_instruments(twin_run: Path, tmp_path: Path) -> None:
    recorded = read_dataset(twin_run)
    stated = recorded.metadata["rig"]["instruments"]
    assert stated["logger"]["cert_id"] == "LOG-123"  # the run recorded the rig description
    out = export_csv(recorded, tmp_path / "csv")
    doc = YAML(typ="safe").load((out / "dataset.yaml").read_text(encoding="utf-8"))
    assert Instruments.model_validate(doc["instruments"]) == Instruments.model_validate(stated)
    imported = read_dataset(out)
    # only what the rig description states, on both sides: a default stays a default
    assert imported.metadata["rig"]["instruments"] == stated
    assert "thermometer" not in imported.metadata["rig"]["instruments"]


def test_diagnose_of_the_export_reads_the_stated_logger(twin_run: Path, tmp_path: Path) -> None:
    imported = read_dataset(export_csv(read_dataset(twin_run), tmp_path / "csv"))
    spec, source = stated_converter(imported)
    assert source == "rig description"
    assert (spec.bits, tuple(spec.range_v)) == (12, (-5.0, 5.0))
    # exact on any CPU: (5 − (−5)) and the division by 2**12 are exact in binary floats
    assert spec.step_v == 10.0 / 4096


def test_tdms_export_round_trips_the_instruments(twin_run: Path, tmp_path: Path) -> None:
    recorded = read_dataset(twin_run)
    imported = read_dataset(export_tdms(recorded, tmp_path / "tdms"))
    assert imported.metadata["rig"]["instruments"] == recorded.metadata["rig"]["instruments"]
    assert stated_converter(imported)[1] == "rig description"


def test_export_without_stated_instruments_writes_none(tmp_path: Path) -> None:
    rig = tmp_path / "rig.yaml"
    rig.write_text("turntable: {plugin: sim}\n", encoding="utf-8")
    out, _ = run(QUICK / "quick-static-2-steps.yaml", rig, tmp_path / "run", False, 3, None,
                 show_progress=False, confirm_prompts="auto")
    exported = export_csv(read_dataset(Path(str(out))), tmp_path / "csv")
    doc = YAML(typ="safe").load((exported / "dataset.yaml").read_text(encoding="utf-8"))
    assert "instruments" not in doc
    assert stated_converter(read_dataset(exported))[1] != "rig description"


@pytest.mark.parametrize("exporter", [export_csv, export_tdms], ids=["csv", "tdms"])
def test_export_keeps_the_plugins_declarations(twin_run: Path, tmp_path: Path,
                                               exporter: Any) -> None:
    """The turntable plugin's declared encoder survives export and import, so the budget of
    an analysis of the export names the declaration, not the stated default encoder."""
    recorded = read_dataset(twin_run)
    declared = recorded.metadata["rig"]["capabilities"]["turntable"]
    assert declared["plugin"] == "sim"  # the run recorded what the twin's table declares
    assert declared["declared"]["encoder_resolution_counts_per_rev"] > 0
    imported = read_dataset(exporter(recorded, tmp_path / "out"))
    assert imported.metadata["rig"]["capabilities"] == recorded.metadata["rig"]["capabilities"]
    constants = RigConstants.from_results(RunResults.model_validate(
        {"procedure": "export", "metadata": {"rig": imported.metadata["rig"]}}))
    note = comp.encoder_resolution(constants, 3600.0).note
    assert note.startswith("declared by the turntable plugin 'sim'"), note


def test_a_corrupt_recorded_declaration_is_named(twin_run: Path, tmp_path: Path) -> None:
    recorded = read_dataset(twin_run)
    rig = dict(recorded.metadata["rig"])
    rig["capabilities"] = {"turntable": {"plugin": "sim",
                                         "declared": {"encoder_resolution_counts_per_rev": -3}}}
    broken = dataclasses.replace(recorded, metadata={**recorded.metadata, "rig": rig})
    with pytest.raises(InputError, match=r"(?s)plugin declarations.*encoder_resolution"):
        export_csv(broken, tmp_path / "csv")
