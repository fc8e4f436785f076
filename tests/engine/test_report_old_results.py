"""``aatest report`` of a results.json written before the engine decided verdicts.

Such a file (schema version 1, or older without ``schema_version``) has no ``verdicts``; the
report never decides them itself, so it is refused with exit 2 naming the file, the missing key
and the command that regenerates it. The analyses' retired ``*_within_datasheet`` flags in an
old file are read and dropped (docs/interfaces.md §1), so the same run re-analysed passes.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from aatest.cli import app
from aatest.engine.analysis.results_file import read_results

SHIPPED = Path(__file__).resolve().parents[2] / "src/aatest/procedures/scale-factor.yaml"
RUNNER = CliRunner()


@pytest.fixture(scope="module")
def current_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A scale-factor run on the twin, with a results.json of the current schema."""
    run_dir = tmp_path_factory.mktemp("current") / "run"
    done = RUNNER.invoke(app, ["run", str(SHIPPED), "--out", str(run_dir), "--no-progress"])
    assert done.exit_code == 0, done.output
    return run_dir


def _old_copy(current: Path, target: Path, schema_version: int | None) -> Path:
    """A copy of the run whose results.json looks as schema 1 (or older) wrote it."""
    shutil.copytree(current, target)
    path = target / "results.json"
    doc: dict[str, Any] = json.loads(path.read_text(encoding="utf-8"))
    del doc["verdicts"], doc["overall"]
    if schema_version is None:
        del doc["schema_version"]  # before the field existed (and outside the schema check)
        entry = doc["analysis"]["scale_factor"]["v_sz"]
        entry["scale_within_datasheet"] = True  # the analysis' own flag of those days
    else:
        doc["schema_version"] = schema_version
    path.write_text(json.dumps(doc), encoding="utf-8")
    return target


@pytest.mark.parametrize("schema_version", [1, None], ids=["schema-1", "no-schema-version"])
def test_report_without_verdicts_exits_2_naming_file_and_fix(
    current_run: Path, tmp_path: Path, schema_version: int | None
) -> None:
    """The message names the file, the missing key and ``aatest analyze``; nothing is lost."""
    run_dir = _old_copy(current_run, tmp_path / "old", schema_version)
    before = (run_dir / "results.json").read_bytes()
    done = RUNNER.invoke(app, ["report", str(run_dir)])
    assert done.exit_code == 2, done.output
    message = " ".join(done.output.split())  # rich may wrap a long line
    assert str(run_dir / "results.json") in message
    assert "no 'verdicts'" in message and f"aatest analyze {run_dir}" in message
    assert (run_dir / "results.json").read_bytes() == before  # the old record is untouched


def test_retired_flags_are_dropped_and_reanalysis_restores_the_report(
    current_run: Path, tmp_path: Path
) -> None:
    """The old file still loads (flag dropped); ``analyze`` then gives verdicts again."""
    run_dir = _old_copy(current_run, tmp_path / "old", None)
    loaded = read_results(run_dir)
    channel = loaded.analysis.scale_factor["v_sz"] if loaded.analysis.scale_factor else None
    assert channel is not None and "scale_within_datasheet" not in channel.model_dump()
    assert loaded.verdicts == [] and "verdicts" not in loaded.model_fields_set
    assert RUNNER.invoke(app, ["analyze", str(run_dir)]).exit_code == 0
    regenerated = json.loads((run_dir / "results.json").read_text(encoding="utf-8"))
    assert regenerated["overall"] == "pass" and regenerated["verdicts"]
    done = RUNNER.invoke(app, ["report", str(run_dir)])
    assert done.exit_code == 0, done.output
