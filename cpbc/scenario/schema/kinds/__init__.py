"""The constraint and law kinds a scenario's ``type:`` may name, and :data:`KINDS`, the registry
of them (see cpbc.scenario.schema.kinds.registry for what a kind declares, where, and why the
registry is a value).

The constraint kinds are declared in their constraints' modules (cpbc.constraints), the law
kinds in this package's ``*_kind`` modules; :data:`KINDS` is what those modules declare, found
by walking both packages in the order of their module names. A new kind is one module and
its test; the schema, the JSON Schema, the scenario reference, the build, the gain check and
the results read it from here.
"""

import cpbc.constraints
import cpbc.scenario.schema.kinds as _laws
from cpbc.constraints.constraint_kind import ConstraintKind
from cpbc.scenario.schema.kinds.registry import (
    Kinds,
    LawKind,
    declared_in,
    declared_kinds,
)
from cpbc.spec.type_names import KindError

KINDS = Kinds.of(declared_kinds(cpbc.constraints, _laws))

__all__ = ["KINDS", "ConstraintKind", "KindError", "Kinds", "LawKind", "declared_in",
           "declared_kinds"]
