"""Every recipe in docs/procedures.md validates and runs on the twin with the outcome it states
(issue 32), and every shipped procedure carries the editor modeline the guide documents."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

from aatest.cli import app
from aatest.schemas.export import render

ROOT = Path(__file__).resolve().parents[1]
GUIDE = ROOT / "docs" / "procedures.md"
SHIPPED = ROOT / "src" / "aatest" / "procedures"
RECIPE = re.compile(r"<!-- recipe: ([\w-]+), outcome: (\w+) -->\n```yaml\n(.*?)```", re.S)
#: what the guide says after each refused recipe: "Outcome: refused, `MESSAGE …`"
REFUSAL = re.compile(r"Outcome: refused, `([^`…]+)")
RUNNER = CliRunner()


def _recipes() -> list[tuple[str, str, str]]:
    return RECIPE.findall(GUIDE.read_text(encoding="utf-8"))


def test_the_guide_has_the_issues_recipes() -> None:
    names = {name: outcome for name, outcome, _text in _recipes()}
    assert names == {"scale-factor-levels": "pass", "production-smoke": "pass",
                     "production-smoke-bias": "refused", "temperature-campaign": "pass",
                     "cross-axis-single": "pass", "cross-axis-one-position": "refused"}


@pytest.mark.parametrize(("name", "outcome", "text"), _recipes(), ids=lambda v: str(v)[:24])
def test_recipe_has_its_stated_outcome(name: str, outcome: str, text: str,
                                       tmp_path: Path) -> None:
    path = tmp_path / f"{name}.yaml"
    path.write_text(text, encoding="utf-8")
    checked = RUNNER.invoke(app, ["validate", str(path)])
    if outcome == "refused":
        assert checked.exit_code == 2, checked.output
        guide = GUIDE.read_text(encoding="utf-8")
        after = guide[guide.index(f"recipe: {name},"):]
        stated = REFUSAL.search(after)
        assert stated and " ".join(stated[1].split()) in " ".join(checked.output.split())
        return
    assert checked.exit_code == 0, checked.output
    done = RUNNER.invoke(app, ["run", str(path), "--out", str(tmp_path / "run"),
                               "--no-progress", "--seed", "11"])
    results = json.loads((tmp_path / "run" / "results.json").read_text())
    assert (done.exit_code, results["overall"]) == (0, outcome), done.output
    assert all(v["verdict"] != "not judged" for v in results["verdicts"])


def test_every_shipped_procedure_has_the_schema_modeline() -> None:
    for path in sorted(SHIPPED.glob("*.yaml")):
        first = path.read_text(encoding="utf-8").splitlines()[0]
        assert first == "# yaml-language-server: $schema=procedure.schema.json", path
    # the copy the modeline names is the generated schema (python -m aatest.schemas.export)
    assert (SHIPPED / "procedure.schema.json").read_text(encoding="utf-8") == render()
