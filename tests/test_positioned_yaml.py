"""Located errors: every schema problem maps back to the line and column of the YAML."""

import pytest
from pydantic import BaseModel, ConfigDict

from aatest.engine.errors import ProcedureError
from aatest.positioned_yaml import parse_yaml, validate_tree


class Inner(BaseModel):
    model_config = ConfigDict(extra="forbid")
    rate_dps: float


class Outer(BaseModel):
    model_config = ConfigDict(extra="forbid")
    name: str
    axes: list[Inner]


def _problems(text: str) -> list[str]:
    tree, data = parse_yaml(text, "p.yaml")
    with pytest.raises(ProcedureError) as info:
        validate_tree(Outer, tree, data, "p.yaml")
    return [str(p) for p in info.value.problems]


def test_every_problem_is_reported_with_its_position() -> None:
    text = "name: x\naxes:\n  - rate_dps: fast\n  - rate_dps: 1\n    colour: red\n"
    problems = _problems(text)
    assert len(problems) == 2
    assert problems[0].startswith("p.yaml:3:5: axes.0.rate_dps: ")
    assert problems[1].startswith("p.yaml:5:5: axes.1.colour: Extra inputs")


def test_missing_field_points_at_its_parent() -> None:
    problems = _problems("name: x\naxes:\n  - {}\n")
    assert problems == ["p.yaml:3:5: axes.0.rate_dps: Field required"]


def test_syntax_error_is_located() -> None:
    with pytest.raises(ProcedureError) as info:
        parse_yaml("name: x\naxes: [1, 2\n", "bad.yaml")
    (problem,) = info.value.problems
    assert problem.file == "bad.yaml" and problem.line >= 2
    assert "YAML syntax" in problem.message


def test_tags_are_not_executed() -> None:
    with pytest.raises(ProcedureError):
        tree, data = parse_yaml("!!python/object/apply:os.system ['true']\n", "evil.yaml")
        validate_tree(Outer, tree, data, "evil.yaml")


def test_duplicate_keys_are_rejected() -> None:
    with pytest.raises(ProcedureError, match=r"dup\.yaml:2"):
        parse_yaml("name: a\nname: b\n", "dup.yaml")
