"""``type: linear_limit``: lower < aᵀx < upper for each row a (a LinearLimit)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from cpbc.constraints import LinearLimit
from cpbc.scenario.schema.common import Vector
from cpbc.scenario.schema.constraint_specs import ConstraintEntrySpec
from cpbc.scenario.schema.kinds.constraint_inputs import ConstraintInputs, row_labels
from cpbc.scenario.schema.kinds.registry import ConstraintKind


class LinearLimitSpec(ConstraintEntrySpec):
    type: Literal["linear_limit"] = Field(
        description=(
            "lower < aᵀx < upper for each row a (the thesis's |θ2 − θ1| < 17π/18)"))
    name: str = Field(
        default="linear_limit", description=(
            "unique name, used by controllers' constraints lists and in the summary"))
    coefficients: list[Vector] = Field(description="the rows a, one per limit")
    lower: Vector = Field(description="lower bound per row")
    upper: Vector = Field(description="upper bound per row")


def build(spec: LinearLimitSpec, given: ConstraintInputs) -> LinearLimit:
    rows = given.rows(spec.coefficients)
    k = rows.shape[0]
    return LinearLimit(rows, given.vector(spec.lower, k, "lower"),
                       given.vector(spec.upper, k, "upper"), row_labels(spec.name, k))


KIND = ConstraintKind(LinearLimitSpec, build, LinearLimit)
