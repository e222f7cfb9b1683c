"""``type: joint_position_limit``: lower < x_i < upper on coordinates (a LinearLimit on rows
of the identity)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from cpbc.constraints import LinearLimit, joint_position_limit
from cpbc.scenario.schema.common import Vector
from cpbc.scenario.schema.constraint_specs import ConstraintEntrySpec, FromModel
from cpbc.scenario.schema.kinds.constraint_inputs import ConstraintInputs
from cpbc.scenario.schema.kinds.registry import ConstraintKind


class JointPositionLimitSpec(ConstraintEntrySpec):
    type: Literal["joint_position_limit"] = Field(
        description=(
            "lower < x_i < upper on coordinates, φ = (x − l)(u − x)"))
    name: str = Field(
        default="joint_position_limit", description=(
            "unique name, used by controllers' constraints lists and in the summary"))
    joints: list[str] | None = Field(
        default=None, description=(
            "the constrained coordinates by joint name; all when omitted"))
    lower: Vector | FromModel = Field(
        description=(
            "lower bounds [rad or m], or from_model (the model's joint ranges)"))
    upper: Vector | FromModel = Field(
        description=(
            "upper bounds [rad or m], or from_model (the model's joint ranges)"))


def build(spec: JointPositionLimitSpec, given: ConstraintInputs) -> LinearLimit:
    idx = given.joints(spec.joints)
    return joint_position_limit(given.limit(spec.lower, "position", 0, idx, "lower"),
                                given.limit(spec.upper, "position", 1, idx, "upper"),
                                given.names, idx)


KIND = ConstraintKind(JointPositionLimitSpec, build, LinearLimit)
