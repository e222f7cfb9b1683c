"""The constraint and law kinds a scenario's ``type:`` may name, and :data:`KINDS`, the registry
of them (see cpbc.scenario.schema.kinds.registry for what a kind declares, where, and why the
registry is a value).

Every kind is declared at the end of its constraint's or law's own module; :data:`KINDS` is
what the modules of cpbc.constraints, cpbc.controllers and cpbc.peers declare, found by
walking those packages in the order of their module names. A new kind is one module and its
test; the schema, the JSON Schema, the scenario reference, the build, the gain check and the
results read it from here.
"""

import cpbc.constraints
import cpbc.controllers
import cpbc.peers
from cpbc.constraints.constraint_kind import ConstraintKind
from cpbc.controllers.law_kind import LawKind
from cpbc.scenario.schema.kinds.registry import Kinds, declared_in, declared_kinds
from cpbc.spec.type_names import KindError

#: The packages whose modules declare kinds, walked in this order.
PACKAGES = (cpbc.constraints, cpbc.controllers, cpbc.peers)
KINDS = Kinds.of(declared_kinds(*PACKAGES))

__all__ = ["KINDS", "PACKAGES", "ConstraintKind", "KindError", "Kinds", "LawKind", "declared_in",
           "declared_kinds"]
