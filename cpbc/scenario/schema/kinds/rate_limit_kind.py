"""``type: rate_limit``: |aᵀẋ| < B for each row a (a RateLimit)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from cpbc.constraints import RateLimit
from cpbc.scenario.schema.common import Positive, Vector
from cpbc.scenario.schema.constraint_specs import ConstraintEntrySpec
from cpbc.scenario.schema.kinds.constraint_inputs import ConstraintInputs, row_labels
from cpbc.scenario.schema.kinds.registry import ConstraintKind


class RateLimitSpec(ConstraintEntrySpec):
    type: Literal["rate_limit"] = Field(description="|aᵀẋ| < B for each row a")
    name: str = Field(
        default="rate_limit", description=(
            "unique name, used by controllers' constraints lists and in the summary"))
    coefficients: list[Vector] = Field(description="the rows a, one per bound")
    bounds: list[Positive] = Field(description="the bound B per row")


def build(spec: RateLimitSpec, given: ConstraintInputs) -> RateLimit:
    rows = given.rows(spec.coefficients)
    k = rows.shape[0]
    return RateLimit(rows, given.vector(spec.bounds, k, "bounds"), row_labels(spec.name, k))


KIND = ConstraintKind(RateLimitSpec, build, RateLimit)
