"""The committed JSON Schema must equal the one generated from the models."""

from __future__ import annotations

import json

from aatest.engine.procedure.schema_export import SCHEMA_PATH, procedure_json_schema, render


def test_committed_schema_is_fresh() -> None:
    committed = SCHEMA_PATH.read_text(encoding="utf-8")
    assert committed == render(), (
        "src/aatest/schemas/procedure.schema.json is stale: run "
        "`python -m aatest.engine.procedure.schema_export` and commit the result")


def test_schema_describes_the_contract_shape() -> None:
    schema = procedure_json_schema()
    assert schema["$schema"].endswith("2020-12/schema")
    assert set(schema["required"]) == {"procedure", "sensor", "steps"}
    assert schema["additionalProperties"] is False
    entry = schema["$defs"]["StepEntry"]
    assert entry["minProperties"] == entry["maxProperties"] == 1
    assert {"sine_sweep", "multi_position", "misalignment", "operator"} <= set(entry["properties"])
    json.dumps(schema)  # serialisable
