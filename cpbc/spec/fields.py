"""The numbers of a scenario entry (finite; expressions of pi allowed) and ``Strict``, the base
of every spec: unknown keys are errors, a validated entry is frozen."""

from __future__ import annotations

import math
from typing import Annotated

from pydantic import AfterValidator, BaseModel, BeforeValidator, ConfigDict, Field

from cpbc.spec.expressions import parse_number


def _finite(v: float) -> float:
    if not math.isfinite(v):
        raise ValueError("must be a finite number")
    return v


Number = Annotated[float, BeforeValidator(parse_number), AfterValidator(_finite)]
Positive = Annotated[Number, Field(gt=0)]
NonNegative = Annotated[Number, Field(ge=0)]
Vector = list[Number]
Gain = Positive | list[Positive]


class Strict(BaseModel):
    # defer_build: a spec's validator is built when a scenario is first validated, not when
    # its module is imported (the Python API imports every constraint and law module)
    model_config = ConfigDict(extra="forbid", frozen=True, defer_build=True)
