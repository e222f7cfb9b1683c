"""python -m cpbc.json_schema: the JSON Schema of scenario files. jsonschema is not a
dependency, so the test checks the schema against every shipped scenario by hand: it parses,
names every top-level key each file uses, requires only keys the file has, and lets a number
be written as an expression."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from cpbc.json_schema import main
from cpbc.resources import scenarios_dir

SCENARIOS = sorted(scenarios_dir().glob("*.yaml"))


@pytest.fixture(scope="module")
def schema(tmp_path_factory) -> dict:
    out = tmp_path_factory.mktemp("schema") / "scenario.schema.json"
    assert main(["--out", str(out)]) == 0
    return json.loads(out.read_text(encoding="utf-8"))


def test_the_schema_offers_an_arm_and_a_part_i_scenario(schema: dict) -> None:
    assert schema["$schema"].endswith("2020-12/schema")
    assert [r["$ref"] for r in schema["anyOf"]] == ["#/$defs/Scenario", "#/$defs/SystemScenario"]
    for name in ("Scenario", "SystemScenario"):
        assert schema["$defs"][name]["additionalProperties"] is False
    target = schema["$defs"]["Scenario"]["properties"]["target"]["items"]
    assert {"type": "number"} in target["anyOf"]  # or an expression, "2*pi/3"
    assert any(s.get("type") == "string" for s in target["anyOf"])


@pytest.mark.parametrize("path", SCENARIOS, ids=[p.stem for p in SCENARIOS])
def test_every_shipped_scenario_fits_the_schema_at_the_top(schema: dict, path: Path) -> None:
    raw = yaml.safe_load(path.read_text())
    model = schema["$defs"]["SystemScenario" if "system" in raw else "Scenario"]
    assert set(raw) <= set(model["properties"]), set(raw) - set(model["properties"])
    assert set(model.get("required", ())) <= set(raw)


def test_stdout_by_default(capsys) -> None:
    assert main([]) == 0
    assert json.loads(capsys.readouterr().out)["title"] == "cpbc scenario"
