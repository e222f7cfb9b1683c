"""The constraint and law kinds a scenario's ``type:`` may name, one module each, and
:data:`KINDS`, the registry built from them (see cpbc.scenario.schema.kinds.registry for what a kind
declares, where, and why the registry is a value).

A new kind is one module here (its spec, its factory, its declarations, ``KIND``), one line
in the tuple below, and its test; the schema, the JSON schema, the scenario reference, the
build, the gain check and the results read it from there.
"""

from cpbc.scenario.schema.kinds import (
    bpbc_kind,
    cbf_qp_kind,
    clearance_kind,
    cpbc_kind,
    joint_position_limit_kind,
    joint_rate_limit_kind,
    kinetic_energy_limit_kind,
    linear_limit_kind,
    pd_kind,
    point_outside_sphere_kind,
    rate_limit_kind,
    recentred_kind,
)
from cpbc.scenario.schema.kinds.registry import ConstraintKind, KindError, Kinds, LawKind

KINDS = Kinds(
    constraints=(
        joint_position_limit_kind.KIND,
        linear_limit_kind.KIND,
        point_outside_sphere_kind.KIND,
        joint_rate_limit_kind.KIND,
        rate_limit_kind.KIND,
        kinetic_energy_limit_kind.KIND,
        clearance_kind.KIND,
    ),
    laws=(pd_kind.KIND, cpbc_kind.KIND, recentred_kind.KIND, bpbc_kind.KIND, cbf_qp_kind.KIND),
)

__all__ = ["KINDS", "ConstraintKind", "KindError", "Kinds", "LawKind"]
