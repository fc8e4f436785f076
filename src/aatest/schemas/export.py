"""JSON Schemas generated from the pydantic models (never hand-edited).

Two documents, both committed under ``src/aatest/schemas/`` and checked for staleness by
``tests/schemas/test_schema_fresh.py``:

- ``procedure.schema.json``: the procedure YAML, for editors (completion and checking);
- ``results.schema.json``: ``results.json`` (:class:`aatest.results.RunResults`), for anyone
  who reads results without aatest.

Example
-------
Regenerate the committed copies after changing the models::

    python -m aatest.schemas.export                          # writes the committed copies
    aatest schema > procedure.schema.json                    # the same documents on stdout
    aatest schema --results > results.schema.json

>>> procedure_json_schema()["title"]
'aatest procedure'
>>> results_json_schema()["title"]
'aatest results'
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

from pydantic import BaseModel

from aatest.engine.procedure.models import Procedure
from aatest.results import RunResults

#: where the committed copies live (package data, shipped with the wheel)
SCHEMA_DIR = Path(__file__).resolve().parent
SCHEMA_PATH = SCHEMA_DIR / "procedure.schema.json"
RESULTS_SCHEMA_PATH = SCHEMA_DIR / "results.schema.json"
#: a copy beside the shipped procedures, so their modeline names it without leaving the folder
PROCEDURES_SCHEMA_PATH = SCHEMA_DIR.parent / "procedures" / "procedure.schema.json"
SCHEMA_ID = "https://aatest.invalid/schemas/procedure.schema.json"
RESULTS_SCHEMA_ID = "https://aatest.invalid/schemas/results.schema.json"


def _schema(model: type[BaseModel], schema_id: str, title: str) -> dict[str, Any]:
    schema = model.model_json_schema(mode="validation")
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", "$id": schema_id,
            **schema, "title": title}


def _builtin_analysis_options() -> tuple[dict[str, Any], dict[str, Any]]:
    """Options schemas of the analyses aatest itself ships (name → schema), and their $defs.

    Third-party analyses are not listed (the committed schema must not depend on what else is
    installed); their options stay a free mapping, checked by the loader.
    """
    from aatest.engine.analysis import plugins

    options: dict[str, Any] = {}
    defs: dict[str, Any] = {}
    for name in plugins.installed_names():
        plugin = plugins.load(name)
        if plugin.distribution == "aatest":
            schema = plugin.cls.Options.model_json_schema()
            defs |= schema.pop("$defs", {})
            options[name] = schema
    return options, defs


def procedure_json_schema() -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of a procedure file, with the options of every built-in
    analysis under ``analysis: [{name: {options}}]``."""
    schema = _schema(Procedure, SCHEMA_ID, "aatest procedure")
    options, defs = _builtin_analysis_options()
    for branch in schema["properties"]["analysis"]["items"]["anyOf"]:
        if branch.get("type") == "object":
            branch["properties"] = options
    schema.setdefault("$defs", {}).update(defs)
    return schema


def results_json_schema() -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of ``results.json``."""
    return _schema(RunResults, RESULTS_SCHEMA_ID, "aatest results")


def render(results: bool = False) -> str:
    """A schema as the exact text committed (2-space indent, trailing newline)."""
    schema = results_json_schema() if results else procedure_json_schema()
    return json.dumps(schema, indent=2) + "\n"  # as `aatest schema [--results]` prints it


def install_schemas(directory: Path) -> Path:
    """Write both schemas into ``directory`` (created) for an editor; return the procedure
    schema's absolute path (what a ``# yaml-language-server: $schema=`` modeline names)."""
    directory.mkdir(parents=True, exist_ok=True)
    for name, results in ((SCHEMA_PATH.name, False), (RESULTS_SCHEMA_PATH.name, True)):
        (directory / name).write_text(render(results), encoding="utf-8")
    return (directory / SCHEMA_PATH.name).resolve()


def main(argv: list[str] | None = None) -> int:
    """Write both committed copies; ``-`` prints the procedure schema (``- --results``: the
    results schema) to stdout instead."""
    args = sys.argv[1:] if argv is None else argv
    if args and args[0] == "-":
        sys.stdout.write(render("--results" in args))
        return 0
    for path, results in ((SCHEMA_PATH, False), (RESULTS_SCHEMA_PATH, True),
                          (PROCEDURES_SCHEMA_PATH, False)):
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(render(results), encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
