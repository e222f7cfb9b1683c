"""Bounded-torque PBC with joint rate limits (Theorem 7.7)."""

from __future__ import annotations

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.constraints.rate_limit import RateLimit
from cpbc.controllers.controller import positive_vector
from cpbc.controllers.cpbc import CPBC
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


def bounded_damping(task_damping: StateDamping | None, law: str) -> float:
    """sup ‖F‖ of a bounded-torque law's task damping (0 without one), or a CpbcError when it
    is unbounded."""
    if task_damping is None:
        return 0.0
    bound = task_damping.force_bound
    if bound is None or not np.isfinite(bound):
        raise CpbcError(f"{law}: its torque bound needs bounded task damping (TaskTanhDamping, "
                        "D_x tanh(Γ_x v)), not the linear one")
    return float(bound)


class BPBC(CPBC):
    """Theorem 7.7 (eq. 7.17): the CPBC law with U = Σ (K_Pi/ξ_i) ln cosh(ξ_i x̃_i) and damping
    K_D tanh(Γẋ), enforcing per-joint rate limits |ẋ_i| < B_i only.

    Its torque is bounded by (7.32):

        ‖τ‖ ≤ ζ_g + λmax(K_P) + λmax(K_D) + ζ_c‖B‖² + ζ_f‖B‖

    with ζ_g, ζ_c, ζ_f estimated from the model (cpbc.model.bounds). ``torque_bound`` is that
    number as the thesis states it; ``torque_bound_norm`` replaces λmax(K) by ‖diag K‖₂, since
    ‖K tanh(·)‖ can reach ‖diag K‖₂ > λmax(K) when several entries saturate together.

    The proof of (7.32) bounds the potential's force only by sup ‖∂U/∂x‖, so ``potential``
    may be any U with a posture spring and a bounded gradient (a task potential of ln cosh
    and orientation springs): λmax(K_P) is then replaced by the potential's
    ``gradient_bound`` (``stated`` in ``torque_bound``, ``norm`` in ``torque_bound_norm``).
    A ``task_damping`` term must be bounded (TaskTanhDamping); its ``force_bound`` is added.
    """

    type_name = "bpbc"

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
        if constraints.configuration or not constraints.velocity or not all(
            isinstance(c, RateLimit) and c.is_per_joint for c in constraints.velocity
        ):
            raise CpbcError(
                "bpbc (Theorem 7.7) enforces per-joint rate limits only: give it "
                "joint_rate_limit constraints and no position, obstacle or energy constraints"
            )
        rates = [c for c in constraints.velocity if isinstance(c, RateLimit)]
        limited = np.concatenate([c.joint_index for c in rates if c.joint_index is not None])
        if sorted(limited.tolist()) != list(range(model.n)):
            raise CpbcError(
                "bpbc needs exactly one rate limit on every joint for its torque bound (7.32)"
            )
        self.xi = positive_vector(xi, model.n, "xi")
        self.gamma = positive_vector(gamma, model.n, "gamma")
        self.potential = JointLogCoshSpring(self.target, self.kp, self.xi) if (
            potential is None) else require_posture(potential, self.type_name)
        spring = require_bounded(self.potential, self.type_name)
        extra = bounded_damping(task_damping, self.type_name)
        self.damping = TanhDamping(self.kd, self.gamma)
        bounds = np.zeros(model.n)
        for c in rates:
            bounds[c.joint_index] = c.bounds
        self.rate_bounds = bounds
        self.model_bounds = model_bounds or estimate_bounds(model)
        zb = self.model_bounds
        rate_norm = float(np.linalg.norm(bounds))
        tail = (zb.gravity + zb.coriolis * rate_norm**2 + zb.friction * rate_norm + zb.coulomb
                + extra)
        self.torque_bound = tail + (spring.stated + float(self.kd.max()))
        self.torque_bound_norm = tail + (spring.norm + float(np.linalg.norm(self.kd)))
