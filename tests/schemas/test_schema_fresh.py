"""The committed JSON Schema must equal the one generated from the models."""

from __future__ import annotations

import json

from aatest.schemas.export import SCHEMA_PATH, procedure_json_schema, render


def test_committed_schema_is_fresh() -> None:
    committed = SCHEMA_PATH.read_text(encoding="utf-8")
    assert committed == render(), (
        "src/aatest/schemas/procedure.schema.json is stale: run "
        "`python -m aatest.schemas.export` and commit the result")


def test_schema_describes_the_contract_shape() -> None:
    schema = procedure_json_schema()
    assert schema["$schema"].endswith("2020-12/schema")
    assert set(schema["required"]) == {"procedure", "sensor", "steps"}
    assert schema["additionalProperties"] is False
    entry = schema["$defs"]["StepEntry"]
    assert entry["minProperties"] == entry["maxProperties"] == 1
    assert {"sine_sweep", "multi_position", "misalignment", "operator"} <= set(entry["properties"])
    json.dumps(schema)  # serialisable


def test_committed_results_schema_is_fresh() -> None:
    from aatest.schemas.export import RESULTS_SCHEMA_PATH

    assert RESULTS_SCHEMA_PATH.read_text(encoding="utf-8") == render(results=True), (
        "src/aatest/schemas/results.schema.json is stale: run "
        "`python -m aatest.schemas.export` and commit the result")


def test_results_schema_shape() -> None:
    from aatest.schemas.export import results_json_schema

    schema = results_json_schema()
    assert schema["title"] == "aatest results" and schema["additionalProperties"] is False
    assert {"procedure"} <= set(schema["required"])
    assert {"verdicts", "overall", "schema_version", "certificate_number"} <= set(
        schema["properties"])
    block = schema["$defs"]["AnalysisBlock"]
    assert "extra" not in block["properties"] and block["additionalProperties"] is True
    point = schema["$defs"]["FrfPoint"]["properties"]
    assert {"gain_expanded_uncertainty_db", "phase_expanded_uncertainty_deg", "gain_budget",
            "phase_budget", "expanded_uncertainty"} <= set(point)


def test_cli_prints_the_committed_schemas() -> None:
    from typer.testing import CliRunner

    from aatest.cli import app
    from aatest.schemas.export import RESULTS_SCHEMA_PATH

    runner = CliRunner()
    assert runner.invoke(app, ["schema"]).output == SCHEMA_PATH.read_text(encoding="utf-8")
    out = runner.invoke(app, ["schema", "--results"]).output
    assert out == RESULTS_SCHEMA_PATH.read_text(encoding="utf-8")


def test_procedure_schema_knows_the_builtin_analysis_options() -> None:
    import jsonschema

    validator = jsonschema.Draft202012Validator(procedure_json_schema())
    base = {"procedure": "x", "sensor": {"model": "m"}, "steps": [{"static": {}}]}
    good = ["sync", {"scale_factor": {"reference": "fit", "orders": [1, 9]}},
            {"transfer_function": {"delay": "none"}}, {"third_party": {"anything": 1}}]
    assert list(validator.iter_errors(base | {"analysis": good})) == []
    for bad in ({"scale_factor": {"referenc": "fit"}}, {"frf": {"harmonics": "six"}},
                {"frf": {}, "bias": {}}):
        assert list(validator.iter_errors(base | {"analysis": [bad]})), bad
