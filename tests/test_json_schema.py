"""python -m cpbc.json_schema: the JSON Schema of scenario files. The test checks it parses,
names every top-level key each file uses, requires only keys the file has, lets a number be
written as an expression, and (with jsonschema, a test dependency, as an editor would) accepts
every shipped scenario whole and refuses a misspelled key."""

from __future__ import annotations

import json
from pathlib import Path

import jsonschema
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
    target = next(v for v in schema["$defs"]["Scenario"]["properties"]["target"]["anyOf"]
                  if v.get("type") == "array")["items"]  # or null: a goal instead
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


@pytest.mark.parametrize("path", SCENARIOS, ids=[p.stem for p in SCENARIOS])
def test_every_shipped_scenario_validates_whole(schema: dict, path: Path) -> None:
    raw = yaml.safe_load(path.read_text())
    errors = list(jsonschema.Draft202012Validator(schema).iter_errors(raw))
    assert errors == [], [e.message for e in errors]


def test_a_misspelled_key_is_refused_as_an_editor_would(schema: dict) -> None:
    raw = yaml.safe_load((SCENARIOS[0]).read_text())
    raw["simulation"]["duraton"] = 1.0
    assert list(jsonschema.Draft202012Validator(schema).iter_errors(raw))
