"""Joint springs toward a set point x_d: today's potentials of the joint laws (eqs. 6.7 and
7.18), and the posture spring toward x_n that every task potential needs."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.packing import Packed
from cpbc.controllers.controller import positive_vector
from cpbc.controllers.potentials.log_cosh import LogCoshSum
from cpbc.controllers.potentials.potential import GradientBound, OfTheJoints, Placed
from cpbc.kernels.law_terms import joint_spring, pack_joint_spring, pack_log_cosh_spring


def _set_point(target: object) -> Array:
    a = np.array(target, dtype=float)
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class JointSpring(OfTheJoints):
    """U = ½ x̃ᵀ K x̃, x̃ = x − x_d (eq. 6.7), ∂U/∂x = K x̃, K diagonal > 0.

    Attributes:
        target: x_d (the joint set point, or the posture x_n), shape (n,).
        stiffness: K, a number or n numbers, > 0.
    """

    target: Array
    stiffness: Array

    def __post_init__(self) -> None:
        target = _set_point(self.target)
        object.__setattr__(self, "target", target)
        object.__setattr__(self, "stiffness",
                           positive_vector(self.stiffness, target.shape[0], "stiffness"))

    @property
    def gradient_bound(self) -> GradientBound | None:
        return None

    def evaluate(self, at: Placed) -> tuple[float, Array]:
        return self.evaluate_toward(at, self.target)

    def evaluate_toward(self, at: Placed, goal: Array) -> tuple[float, Array]:
        """U and ∂U/∂x toward the set point ``goal`` in place of the spring's own (a moving
        posture x_n(s), cpbc.reference.target) (cpbc.kernels.law_terms.joint_spring)."""
        grad = np.empty(goal.shape[0])
        return joint_spring(at.x, goal, self.stiffness, grad), grad

    def packed(self, toward: Array | None = None) -> tuple[Packed, ...] | None:
        """x_d and K for a law's kernel (cpbc.kernels.law_terms), unless a subclass
        overrides ``evaluate`` or ``evaluate_toward``; with ``toward``, x_d is that array,
        read again before each step (a moving posture: ``Packed.live``)."""
        cls = type(self)
        if cls.evaluate is not JointSpring.evaluate or (
                cls.evaluate_toward is not JointSpring.evaluate_toward):
            return None
        goal = self.target if toward is None else toward
        return (pack_joint_spring(goal, self.stiffness, moving=toward is not None),)


@dataclass(frozen=True)
class JointLogCoshSpring(OfTheJoints):
    """U = Σ (K_i/ξ_i) ln cosh(ξ_i x̃_i) (eq. 7.18), ∂U/∂x = K tanh(Ξx̃), bounded by K.

    Attributes:
        target: x_d (the joint set point, or the posture x_n), shape (n,).
        stiffness: K, a number or n numbers, > 0.
        xi: ξ, a number or n numbers, > 0.
    """

    target: Array
    stiffness: Array
    xi: Array
    _spring: LogCoshSum = field(init=False, repr=False)

    def __post_init__(self) -> None:
        target = _set_point(self.target)
        n = target.shape[0]
        stiffness = positive_vector(self.stiffness, n, "stiffness")
        xi = positive_vector(self.xi, n, "xi")
        object.__setattr__(self, "target", target)
        object.__setattr__(self, "stiffness", stiffness)
        object.__setattr__(self, "xi", xi)
        object.__setattr__(self, "_spring", LogCoshSum(stiffness, xi))

    @property
    def gradient_bound(self) -> GradientBound:
        """‖K tanh(Ξx̃)‖₂ < ‖diag K‖₂; the thesis states λmax(K) (7.32)."""
        return GradientBound(float(np.linalg.norm(self.stiffness)),
                             float(self.stiffness.max()))

    def evaluate(self, at: Placed) -> tuple[float, Array]:
        return self._spring.evaluate(at.x - self.target)

    def evaluate_toward(self, at: Placed, goal: Array) -> tuple[float, Array]:
        """U and ∂U/∂x toward the set point ``goal`` in place of the spring's own."""
        return self._spring.evaluate(at.x - goal)

    def packed(self, toward: Array | None = None) -> tuple[Packed, ...] | None:
        """x_d, K, ξ for a law's kernel (cpbc.kernels.law_terms), unless a subclass
        overrides ``evaluate`` or ``evaluate_toward``; ``toward`` as
        :meth:`JointSpring.packed`."""
        cls = type(self)
        if cls.evaluate is not JointLogCoshSpring.evaluate or (
                cls.evaluate_toward is not JointLogCoshSpring.evaluate_toward):
            return None
        gains, offset = self._spring.tables()
        goal = self.target if toward is None else toward
        return (pack_log_cosh_spring(goal, gains, offset, moving=toward is not None),)
