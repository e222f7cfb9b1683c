"""``type: point_outside_sphere``: a frame's point kept outside a sphere (the thesis's
end-point obstacle), drawn in the scene."""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from cpbc.constraints import PointOutsideSphere
from cpbc.errors import ScenarioError
from cpbc.scenario.schema.common import Positive, Vector
from cpbc.scenario.schema.constraint_specs import ConstraintEntrySpec
from cpbc.scenario.schema.kinds.constraint_inputs import ConstraintInputs, SceneSphere
from cpbc.scenario.schema.kinds.registry import Constraint, ConstraintKind


class PointOutsideSphereSpec(ConstraintEntrySpec):
    type: Literal["point_outside_sphere"] = Field(
        description=(
            "‖p − c‖² − r² > 0 for a frame's point p (the thesis's end-point obstacle)"))
    name: str = Field(
        default="obstacle", description=(
            "unique name, used by controllers' constraints lists and in the summary"))
    frame: str = Field(description="the model frame carrying the point")
    offset: Vector | None = Field(
        default=None, description=(
            "the point in the frame [m]; the frame's origin when omitted"))
    centre: Vector = Field(description="the sphere's centre in the world [m]")
    radius: Positive = Field(description="the sphere's radius [m]")
    # the thesis's obstacle is not a physical body
    collides: bool = Field(
        default=False, description=(
            "make the sphere a physical body in MuJoCo (the thesis's obstacle is not)"))


def build(spec: PointOutsideSphereSpec, given: ConstraintInputs) -> PointOutsideSphere:
    centre = np.zeros(3)
    if len(spec.centre) not in (2, 3):
        raise ScenarioError(given.at("centre"), "needs 2 (planar) or 3 coordinates")
    centre[: len(spec.centre)] = spec.centre
    offset = None if spec.offset is None else given.vector(spec.offset, 3, "offset")
    return PointOutsideSphere(given.model, spec.frame, centre, spec.radius, offset, spec.name)


def scene(spec: PointOutsideSphereSpec, built: Constraint) -> SceneSphere:
    assert isinstance(built, PointOutsideSphere)
    return SceneSphere(spec.name, built.centre, spec.radius, spec.collides)


KIND = ConstraintKind(PointOutsideSphereSpec, build, PointOutsideSphere, scene)
