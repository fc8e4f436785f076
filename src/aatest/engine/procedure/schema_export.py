"""JSON Schema of the procedure YAML, generated from the pydantic models (never hand-edited).

The committed copy ``src/aatest/schemas/procedure.schema.json`` is what editors use for
completion and checking; ``tests/engine/test_schema_fresh.py`` fails when it is stale.

Example
-------
Regenerate the committed copy after changing :mod:`aatest.engine.procedure.models`::

    python -m aatest.engine.procedure.schema_export          # writes src/aatest/schemas/procedure.schema.json
    aatest schema > procedure.schema.json           # the same document on stdout

>>> procedure_json_schema()["title"]
'aatest procedure'
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

from aatest.engine.procedure.models import Procedure

#: where the committed copy lives (package data, shipped with the wheel)
SCHEMA_PATH = Path(__file__).resolve().parents[2] / "schemas" / "procedure.schema.json"
SCHEMA_ID = "https://aatest.invalid/schemas/procedure.schema.json"


def procedure_json_schema() -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of a procedure file."""
    schema = Procedure.model_json_schema(mode="validation")
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", "$id": SCHEMA_ID,
            **schema, "title": "aatest procedure"}


def render() -> str:
    """The schema as the exact text committed (2-space indent, trailing newline)."""
    return json.dumps(procedure_json_schema(), indent=2) + "\n"  # as `aatest schema` prints it


def main(argv: list[str] | None = None) -> int:
    """Write the schema to ``argv[0]`` (default: the committed copy); ``-`` means stdout."""
    args = sys.argv[1:] if argv is None else argv
    target = args[0] if args else str(SCHEMA_PATH)
    if target == "-":
        sys.stdout.write(render())
    else:
        Path(target).parent.mkdir(parents=True, exist_ok=True)
        Path(target).write_text(render(), encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
