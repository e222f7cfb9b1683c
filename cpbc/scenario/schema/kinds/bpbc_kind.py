"""``type: bpbc`` and ``bpbc_ke``: the bounded laws (Theorem 7.7, Corollary 7.8), whose
spring K_P tanh(Ξx̃) and damping K_D tanh(Γẋ) saturate."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import Field

from cpbc.controllers import BPBC, BPBCKineticEnergy
from cpbc.controllers.controller import Controller
from cpbc.scenario.schema.common import Gain
from cpbc.scenario.schema.controller_specs import ConstrainedLawSpec, ShapingSpec
from cpbc.scenario.schema.kinds.law_inputs import LawInputs, shaping, tanh_slopes
from cpbc.scenario.schema.kinds.registry import LawKind


class BPBCSpec(ConstrainedLawSpec):
    type: Literal["bpbc", "bpbc_ke"] = Field(
        description=(
            "bpbc: Theorem 7.7, bounded torque, a joint_rate_limit on every joint; bpbc_ke: "
            "Corollary 7.8, one kinetic_energy_limit"))
    xi: Gain = Field(
        default=1.0, description=(
            "Ξ of the ln cosh potential: one number or one per coordinate"))
    gamma: Gain = Field(
        default=1.0, description=(
            "Γ of the K_D tanh(Γẋ) damping: one number or one per coordinate"))
    shaping: ShapingSpec | None = Field(
        default=None, description=(
            "the barrier's shaping s: identity, power (α) or tanh (σ)"))


def build(spec: BPBCSpec, given: LawInputs) -> Controller:
    law = BPBC if spec.type == "bpbc" else BPBCKineticEnergy
    gains: dict[str, Any] = dict(given.gains)
    return law(given.model, given.target, given.constraint_set(spec.constraints),
               xi=spec.xi, gamma=spec.gamma, shaping=shaping(spec.shaping),
               model_bounds=given.model_bounds(), **gains)


KINDS = (LawKind(
    BPBCSpec, build, slopes=tanh_slopes,
    examples={"bpbc": {"constraints": ["rates"]}, "bpbc_ke": {"constraints": ["energy"]}},
    goal_types=("bpbc", "bpbc_ke")),)
