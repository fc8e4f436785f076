"""Validation of results.json documents against the committed results.schema.json."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

_SCHEMA = Path(__file__).parents[1] / "src" / "aatest" / "schemas" / "results.schema.json"


def results_validator() -> Any:
    """A draft 2020-12 validator of the committed results schema."""
    import jsonschema

    return jsonschema.Draft202012Validator(json.loads(_SCHEMA.read_text(encoding="utf-8")))


def engine_results(root: Path) -> Iterator[tuple[Path, Any]]:
    """Every results.json under ``root`` that the engine wrote (it always writes
    ``schema_version``); hand-made fixtures and deliberately corrupted copies are left out."""
    for path in sorted(root.rglob("results.json")):
        try:
            doc = json.loads(path.read_text(encoding="utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError):
            continue
        if isinstance(doc, dict) and "schema_version" in doc:
            yield path, doc


def assert_valid_results(root: Path) -> int:
    """Validate every engine-written results.json under ``root``; return how many there were."""
    validator = results_validator()
    count = 0
    for path, doc in engine_results(root):
        errors = sorted(validator.iter_errors(doc), key=lambda e: list(e.absolute_path))
        assert not errors, f"{path} violates results.schema.json: " + "; ".join(
            f"{'/'.join(map(str, e.absolute_path))}: {e.message[:200]}" for e in errors[:5])
        count += 1
    return count
