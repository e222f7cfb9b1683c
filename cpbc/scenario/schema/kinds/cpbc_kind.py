"""``type: cpbc`` and ``cpbc_ke``: the constrained PD with a barrier (Theorem 6.9, and
Corollary 6.11 with one kinetic-energy limit)."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import Field

from cpbc.controllers import CPBC, CPBCKineticEnergy
from cpbc.controllers.controller import Controller
from cpbc.scenario.schema.controller_specs import ConstrainedLawSpec, ShapingSpec
from cpbc.scenario.schema.kinds.law_inputs import LINEAR, LawInputs, shaping
from cpbc.scenario.schema.kinds.registry import LawKind


class CPBCSpec(ConstrainedLawSpec):
    type: Literal["cpbc", "cpbc_ke"] = Field(
        description=(
            "cpbc: Theorem 6.9, any configuration and velocity constraints; cpbc_ke: "
            "Corollary 6.11, configuration constraints and one kinetic_energy_limit"))
    shaping: ShapingSpec | None = Field(
        default=None, description=(
            "the barrier's shaping s: identity, power (α) or tanh (σ)"))


def build(spec: CPBCSpec, given: LawInputs) -> Controller:
    law = CPBC if spec.type == "cpbc" else CPBCKineticEnergy
    gains: dict[str, Any] = dict(given.gains)
    return law(given.model, given.target, given.constraint_set(spec.constraints),
               shaping=shaping(spec.shaping), **gains)


KINDS = (LawKind(
    CPBCSpec, build, slopes=LINEAR,
    examples={"cpbc": {"constraints": ["limits", "rates"]},
              "cpbc_ke": {"constraints": ["limits", "energy"]}},
    goal_types=("cpbc", "cpbc_ke")),)
