"""``python -m cpbc.json_schema [-o FILE]``: the JSON Schema of scenario files, for editors.

One schema accepts both kinds of scenario: an arm's (:class:`cpbc.scenario.Scenario`) and a
Part I system's (:class:`cpbc.scenario.schema.SystemScenario`, the files with a ``system:``
block), as pydantic describes them. Where a scenario takes a number it also takes an
expression such as ``"2*pi/3"`` (cpbc.spec.expressions), so those places accept a string
too. YAML files point to it with a first line
``# yaml-language-server: $schema=scenario.schema.json`` (VS Code's YAML extension, and
other editors with the YAML language server).

The module is not ``cpbc.schema``: cpbc.scenario.schema, the models themselves, has that
name, and no two modules of the package share one.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from pydantic import BaseModel
from pydantic.json_schema import (
    GenerateJsonSchema,
    JsonSchemaMode,
    JsonSchemaValue,
    models_json_schema,
)
from pydantic_core import core_schema

from cpbc.scenario.schema import Scenario, SystemScenario
from cpbc.spec.expressions import parse_number

DIALECT = "https://json-schema.org/draft/2020-12/schema"


class _Expressions(GenerateJsonSchema):
    """pydantic's schema, with a number that may be written as an expression."""

    def function_before_schema(
        self, schema: core_schema.BeforeValidatorFunctionSchema
    ) -> JsonSchemaValue:
        inner = super().function_before_schema(schema)
        if schema["function"].get("function") is not parse_number:
            return inner
        expression = {"type": "string", "description": "an expression: 2*pi/3, 1e-3, …"}
        return {"anyOf": [inner, expression]}


def scenario_schema() -> dict[str, Any]:
    """The JSON Schema of a scenario file: an arm's or a Part I system's."""
    models: list[tuple[type[BaseModel], JsonSchemaMode]] = [
        (Scenario, "validation"), (SystemScenario, "validation")]
    refs, schema = models_json_schema(models, schema_generator=_Expressions)
    return {
        "$schema": DIALECT,
        "title": "cpbc scenario",
        "description": "A scenario of python -m cpbc.run: an arm's, or a Part I system's "
                       "(with a system: block).",
        "anyOf": [refs[m] for m in models],
        **schema,
    }


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m cpbc.json_schema",
        description="Write the JSON Schema of scenario files (arms and Part I systems).")
    parser.add_argument("-o", "--out", type=Path, default=None,
                        help="file to write (default: standard output)")
    args = parser.parse_args(argv)
    text = json.dumps(scenario_schema(), indent=2, ensure_ascii=False) + "\n"
    if args.out is None:
        sys.stdout.write(text)
    else:
        args.out.write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
