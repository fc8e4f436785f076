"""Safe YAML loading that remembers where every value came from.

pydantic reports errors by path (``steps.3.sine.frequency_hz``); this module maps each path
back to the line and column in the file, so every problem prints as
``FILE:LINE:COLUMN: field: message`` and all problems are reported at once.

Every YAML file the tool reads (procedures, rigs, lab profiles, ``dataset.yaml``, model files,
station uploads) goes through :func:`parse_yaml`, which bounds what a small file can cost:
aliases (``*name``) are refused, so a kilobyte "billion laughs" file cannot expand into
gigabytes, and nesting deeper than :data:`MAX_DEPTH` is refused before Python's recursion
limit is reached. Neither is used by any file the tool documents.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, TypeVar

from pydantic import BaseModel, ValidationError
from ruamel.yaml import YAML
from ruamel.yaml.comments import CommentedMap, CommentedSeq
from ruamel.yaml.composer import Composer, ComposerError, MaxDepthExceededError
from ruamel.yaml.error import MarkedYAMLError, YAMLError
from ruamel.yaml.events import AliasEvent

from aatest.engine.errors import Problem, ProcedureError

M = TypeVar("M", bound=BaseModel)

#: deepest nesting of mappings and sequences accepted (procedures nest about 6 levels)
MAX_DEPTH = 64


class NoAliasComposer(Composer):
    """ruamel's composer refusing aliases where they appear (their expansion is unbounded)."""

    def compose_node(self, parent: Any, index: Any) -> Any:
        """Compose one node; an alias is a located error instead of a shared node."""
        if self.parser.check_event(AliasEvent):
            event = self.parser.get_event()
            raise ComposerError(None, None, f"alias *{event.anchor} is not accepted (anchors "
                                "and aliases are refused: their expansion is unbounded)",
                                event.start_mark)
        return super().compose_node(parent, index)


def safe_yaml() -> YAML:
    """The one YAML loader of the tool: round-trip (positions), no aliases, bounded depth."""
    yaml = YAML(typ="rt")
    yaml.allow_duplicate_keys = False
    yaml.Composer = NoAliasComposer
    yaml.max_depth = MAX_DEPTH
    return yaml


def _plain(node: Any) -> Any:
    """Round-trip nodes → plain dicts/lists/scalars (pydantic must not see ruamel types)."""
    if isinstance(node, CommentedMap):
        return {_plain_key(k): _plain(v) for k, v in node.items()}
    if isinstance(node, CommentedSeq):
        return [_plain(v) for v in node]
    for scalar in (str, bool, int, float):  # bool before int: a bool is an int
        if isinstance(node, scalar):
            return scalar(node)
    return node


def _plain_key(key: Any) -> Any:
    """Keep numeric and boolean mapping keys, turn every other key into ``str``."""
    return key if isinstance(key, (int, float, bool)) else str(key)


def parse_yaml(text: str, filename: str) -> tuple[Any, Any]:
    """Parse YAML safely; return (round-trip tree with positions, plain data).

    The round-trip loader builds only plain mappings, sequences and scalars (no Python objects,
    no tags executed), so this is as safe as ``yaml.safe_load``; aliases and nesting deeper
    than :data:`MAX_DEPTH` are refused (:func:`safe_yaml`), so the cost is linear in the text.
    """
    try:
        tree = safe_yaml().load(text)
    except MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line, col = (mark.line + 1, mark.column + 1) if mark is not None else (1, 1)
        msg = " ".join(str(p) for p in (exc.context, exc.problem) if p) or "invalid YAML"
        if isinstance(exc, MaxDepthExceededError):
            msg = f"nested deeper than {MAX_DEPTH} levels (refused)"
        raise ProcedureError([Problem(filename, line, col, "", f"YAML syntax: {msg}")]) from exc
    except (YAMLError, ValueError, TypeError, RecursionError) as exc:
        raise ProcedureError([Problem(filename, 1, 1, "", f"YAML: {exc}")]) from exc
    return tree, _plain(tree)


def locate(tree: Any, path: tuple[Any, ...]) -> tuple[int, int]:
    """Line and column (1-based) of the deepest node of ``path`` present in ``tree``."""
    line, col = 1, 1
    node = tree
    for key in path:
        if isinstance(node, CommentedMap) and key in node:
            try:
                line, col = node.lc.key(key)
                line, col = line + 1, col + 1
            except (KeyError, TypeError, AttributeError):
                pass
            node = node[key]
        elif isinstance(node, CommentedSeq) and isinstance(key, int) and 0 <= key < len(node):
            try:
                line, col = node.lc.item(key)
                line, col = line + 1, col + 1
            except (KeyError, TypeError, AttributeError, IndexError):
                pass
            node = node[key]
        else:
            break
    return line, col


def problems_from_validation(exc: ValidationError, tree: Any, filename: str) -> list[Problem]:
    """One located problem per pydantic error."""
    problems = []
    for err in exc.errors(include_url=False):
        loc = tuple(err.get("loc", ()))
        # pydantic inserts union-member tags (e.g. 'function-after[...]') into paths; skip them
        path = tuple(p for p in loc if isinstance(p, int) or "[" not in str(p))
        line, col = locate(tree, path)
        field = ".".join(str(p) for p in path)
        message = err.get("msg", "invalid")
        problems.append(Problem(filename, line, col, field, message + _unit_hint(path, err)))
    return problems


#: field-name suffix → (unit, example) for errors on a number written with its unit
UNIT_HINTS: tuple[tuple[str, str, str], ...] = (
    ("_hz", "Hz", "1000"), ("_dps2", "°/s²", "400"), ("_dps", "°/s", "100"),
    ("_deg", "degrees", "90"), ("_s", "seconds", "60"), ("_c", "°C", "25"),
    ("_pct_fr", "% of full range", "0.05"), ("_pct", "%", "1.0"), ("_v", "volts", "0.01"),
    ("_per_c", "1/°C", "0.0005"),
)


def _unit_hint(path: tuple[Any, ...], err: Any) -> str:
    """For a number field given text (``1 kHz``): say the unit and give an example."""
    if not err.get("type", "").startswith(("float", "int")) or not isinstance(err.get("input"),
                                                                             str):
        return ""
    keys = [p for p in path if isinstance(p, str)]
    name = keys[-1] if keys else ""
    for suffix, unit, example in sorted(UNIT_HINTS, key=lambda h: -len(h[0])):
        if name.endswith(suffix):
            return f" (got {err['input']!r}; expected a number in {unit}, e.g. {example})"
    return f" (got {err['input']!r}; expected a plain number)"


def validate_tree(model: type[M], tree: Any, data: Any, filename: str) -> M:
    """Validate plain ``data`` against ``model``; raise one error listing every problem."""
    if not isinstance(data, dict):
        raise ProcedureError([Problem(filename, 1, 1, "", "expected a mapping at the top level")])
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise ProcedureError(problems_from_validation(exc, tree, filename)) from exc


def read_text(path: Path) -> str:
    """Read a UTF-8 input file, translating OS errors into a located input error."""
    try:
        return path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ProcedureError([Problem(str(path), 1, 1, "", f"cannot read file: {exc}")]) from exc


def load_model_file(path: Path, model: type[M]) -> M:
    """Load and validate one YAML file as ``model``."""
    tree, data = parse_yaml(read_text(path), str(path))
    return validate_tree(model, tree, data, str(path))
