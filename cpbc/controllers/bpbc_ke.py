"""Bounded-torque PBC with a kinetic-energy bound (Corollary 7.8)."""

from __future__ import annotations

from typing import Any, Literal

import numpy as np
from pydantic import Field

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.controllers.bpbc import BPBC, bounded_damping
from cpbc.controllers.controller import Controller, positive_vector
from cpbc.controllers.cpbc_ke import CPBCKineticEnergy
from cpbc.controllers.law_kind import LawInputs, LawKind, shaping, tanh_slopes
from cpbc.controllers.law_specs import ShapedLawSpec
from cpbc.controllers.potentials import (
    JointLogCoshSpring,
    Potential,
    require_bounded,
    require_posture,
)
from cpbc.controllers.shaping import Shaping
from cpbc.controllers.terms import StateDamping, TanhDamping
from cpbc.errors import CpbcError
from cpbc.model.bounds import ModelBounds, estimate_bounds
from cpbc.model.robot_model import RobotModel
from cpbc.spec.fields import Gain


class BPBCKineticEnergy(CPBCKineticEnergy):
    """Corollary 7.8 (eq. 7.34) with shaping s:

        τ = g − [K_P tanh(Ξx̃) + K_D tanh(Γẋ)] / (1 + ρ/ψ)

    bounded by (7.40): ‖τ‖ ≤ ζ_g + λmax(K_P) + λmax(K_D) (``torque_bound``, as stated) or
    ζ_g + ‖diag K_P‖₂ + ‖diag K_D‖₂ (``torque_bound_norm``; see BPBC). With a bounded task
    ``potential`` (see BPBC) K_P tanh(Ξx̃) is ∂U/∂x, and λmax(K_P), ‖diag K_P‖₂ are replaced
    by its ``gradient_bound``; a bounded ``task_damping`` adds its ``force_bound``.
    """

    type_name = "bpbc_ke"

    def __init__(
        self,
        model: RobotModel,
        target: Array,
        constraints: ConstraintSet,
        kp: object,
        kd: object,
        xi: object = 1.0,
        gamma: object = 1.0,
        shaping: Shaping | None = None,
        model_bounds: ModelBounds | None = None,
        potential: Potential | None = None,
        task_damping: StateDamping | None = None,
    ) -> None:
        super().__init__(model, target, constraints, kp, kd, shaping,
                         task_damping=task_damping)
        if constraints.configuration:
            raise CpbcError(
                "bpbc_ke (Corollary 7.8) enforces only a kinetic-energy limit; remove the "
                "position and obstacle constraints from its list or use cpbc_ke"
            )
        self.xi = positive_vector(xi, model.n, "xi")
        self.gamma = positive_vector(gamma, model.n, "gamma")
        self.potential = JointLogCoshSpring(self.target, self.kp, self.xi) if (
            potential is None) else require_posture(potential, self.type_name)
        spring = require_bounded(self.potential, self.type_name)
        extra = bounded_damping(task_damping, self.type_name)
        self.damping = TanhDamping(self.kd, self.gamma)
        self.model_bounds = model_bounds or estimate_bounds(model)
        g = self.model_bounds.gravity
        self.torque_bound = g + extra + (spring.stated + float(self.kd.max()))
        self.torque_bound_norm = g + extra + (spring.norm + float(np.linalg.norm(self.kd)))


# -- the scenario's ``type: bpbc`` and ``bpbc_ke``: BPBC (cpbc.controllers.bpbc, Theorem 7.7)
# and this law, whose spring K_P tanh(Ξx̃) and damping K_D tanh(Γẋ) saturate
# (cpbc.controllers.law_kind) --------------------------------------------------------------
class BPBCSpec(ShapedLawSpec):
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


def build_bpbc(spec: BPBCSpec, given: LawInputs) -> Controller:
    law = BPBC if spec.type == "bpbc" else BPBCKineticEnergy
    gains: dict[str, Any] = dict(given.gains)
    return law(given.model, given.target, given.constraint_set(spec.constraints),
               xi=spec.xi, gamma=spec.gamma, shaping=shaping(spec.shaping),
               model_bounds=given.model_bounds(), **gains)


KINDS = (LawKind(
    BPBCSpec, build_bpbc, slopes=tanh_slopes,
    examples={"bpbc": {"constraints": ["rates"]}, "bpbc_ke": {"constraints": ["energy"]}},
    goal_types=("bpbc", "bpbc_ke")),)
