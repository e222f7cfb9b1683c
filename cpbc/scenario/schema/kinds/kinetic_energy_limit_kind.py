"""``type: kinetic_energy_limit``: ½ẋᵀDẋ < Ω (a KineticEnergyLimit)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from cpbc.constraints import KineticEnergyLimit
from cpbc.scenario.schema.common import Positive
from cpbc.scenario.schema.constraint_specs import ConstraintEntrySpec
from cpbc.scenario.schema.kinds.constraint_inputs import ConstraintInputs
from cpbc.scenario.schema.kinds.registry import ConstraintKind


class KineticEnergyLimitSpec(ConstraintEntrySpec):
    type: Literal["kinetic_energy_limit"] = Field(description="½ẋᵀDẋ < Ω")
    name: str = Field(
        default="kinetic_energy", description=(
            "unique name, used by controllers' constraints lists and in the summary"))
    limit: Positive = Field(description="Ω [J]")


def build(spec: KineticEnergyLimitSpec, given: ConstraintInputs) -> KineticEnergyLimit:
    return KineticEnergyLimit(given.model, spec.limit, spec.name)


KIND = ConstraintKind(KineticEnergyLimitSpec, build, KineticEnergyLimit)
