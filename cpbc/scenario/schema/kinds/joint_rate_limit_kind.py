"""``type: joint_rate_limit``: |ẋ_i| < B_i on coordinates (a RateLimit on rows of the
identity)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from cpbc.constraints import RateLimit, joint_rate_limit
from cpbc.scenario.schema.common import Positive
from cpbc.scenario.schema.constraint_specs import ConstraintEntrySpec, FromModel
from cpbc.scenario.schema.kinds.constraint_inputs import ConstraintInputs
from cpbc.scenario.schema.kinds.registry import ConstraintKind


class JointRateLimitSpec(ConstraintEntrySpec):
    type: Literal["joint_rate_limit"] = Field(description="|ẋ_i| < B_i on coordinates")
    name: str = Field(
        default="joint_rate_limit", description=(
            "unique name, used by controllers' constraints lists and in the summary"))
    joints: list[str] | None = Field(
        default=None, description=(
            "the constrained coordinates by joint name; all when omitted"))
    bounds: list[Positive] | FromModel = Field(
        description=(
            "the rate bounds B_i [rad/s or m/s], or from_model (the URDF's velocity limits)"))
    # multiplies the bounds (e.g. 0.5 of the URDF's velocity limits)
    scale: Positive = Field(
        default=1.0, description=(
            "factor on the bounds (0.5: half the URDF's velocity limits)"))


def build(spec: JointRateLimitSpec, given: ConstraintInputs) -> RateLimit:
    idx = given.joints(spec.joints)
    bounds = given.limit(spec.bounds, "velocity", 1, idx, "bounds")
    return joint_rate_limit(spec.scale * bounds, given.names, idx)


KIND = ConstraintKind(JointRateLimitSpec, build, RateLimit)
