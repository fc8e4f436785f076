"""One meaning for ``--json``: a flag that prints JSON; the file an option writes is ``--json-out``.

``analyze`` and ``diagnose`` used ``--json PATH`` for a file; the old spelling still works and
warns on stderr, so scripts keep running while they move to ``--json-out``.
"""

from __future__ import annotations

import json
from pathlib import Path

from typer.testing import CliRunner

from aatest.cli import app
from aatest.engine.run.session import run

PROCEDURE = Path(__file__).parent / "data" / "procedures" / "quick-static-2-steps.yaml"


def test_analyze_writes_json_out_and_the_old_spelling_warns(tmp_path: Path) -> None:
    run_dir, results = run(PROCEDURE, None, tmp_path / "run", False, 3, None,
                           show_progress=False, confirm_prompts="auto")
    records = f"sqlite:///{tmp_path / 'records.db'}"
    new, old = tmp_path / "new.json", tmp_path / "old.json"
    done = CliRunner().invoke(app, ["analyze", str(run_dir), "--json-out", str(new),
                                    "--records", records])
    assert done.exit_code == 0, done.output
    assert "deprecated" not in done.output
    done = CliRunner().invoke(app, ["analyze", str(run_dir), "--json", str(old),
                                    "--records", records])
    assert done.exit_code == 0, done.output
    assert "--json PATH is deprecated" in done.output and "--json-out" in done.output
    # the same recording analysed twice: the same procedure and steps in both files
    first, second = json.loads(new.read_text()), json.loads(old.read_text())
    assert first["procedure"] == second["procedure"] == results.procedure
    assert [s["id"] for s in first["steps"]] == [s["id"] for s in second["steps"]]


def test_help_names_json_out_and_hides_the_old_option() -> None:
    for command in ("analyze", "diagnose"):
        shown = CliRunner().invoke(app, [command, "--help"], env={"COLUMNS": "200"}).output
        assert "--json-out" in shown
        assert "--json " not in shown.replace("--json-out", "")
