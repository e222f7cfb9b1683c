"""The damping term of the laws (Chapters 6 and 7); their potentials are in
``cpbc.controllers.potentials``."""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.packing import Packed
from cpbc.kernels.law_terms import (
    joint_damping,
    pack_joint_damping,
    pack_tanh_damping,
    tanh_damping,
)

if TYPE_CHECKING:
    from cpbc.controllers.potentials import Placed


class Damping(Protocol):
    """The damping force of a law, with ẋᵀ force(ẋ) > 0 for ẋ ≠ 0."""

    def force(self, dx: Array) -> Array:
        """The force, shape (n,)."""
        ...


class LinearDamping:
    """K_D ẋ (eq. 6.10)."""

    def __init__(self, kd: Array) -> None:
        self.kd = kd

    def force(self, dx: Array) -> Array:
        """(cpbc.kernels.law_terms.joint_damping)"""
        out = np.empty(dx.shape[0])
        joint_damping(self.kd, dx, out)
        return out

    def packed(self) -> tuple[Packed, ...] | None:
        """K_D for a law's kernel, unless a subclass overrides ``force``."""
        if type(self).force is not LinearDamping.force:
            return None
        return (pack_joint_damping(self.kd),)


class TanhDamping:
    """K_D tanh(Γ ẋ) (eq. 7.17), bounded by K_D."""

    def __init__(self, kd: Array, gamma: Array) -> None:
        self.kd = kd
        self.gamma = gamma

    def force(self, dx: Array) -> Array:
        """(cpbc.kernels.law_terms.tanh_damping)"""
        out = np.empty(dx.shape[0])
        tanh_damping(self.kd, self.gamma, dx, out)
        return out

    def packed(self) -> tuple[Packed, ...] | None:
        """K_D and Γ for a law's kernel, unless a subclass overrides ``force``."""
        if type(self).force is not TanhDamping.force:
            return None
        return (pack_tanh_damping(self.kd, self.gamma),)


class StateDamping(Protocol):
    """A damping force F(x, ẋ) read from the per-step state (task-space damping,
    cpbc.controllers.task_damping), added to a law's joint damping; ẋᵀF ≥ 0 without
    feed-forward."""

    @property
    def frames(self) -> tuple[int, ...]:
        """The frame ids whose kinematics ``force`` reads from the state."""
        ...

    @property
    def force_bound(self) -> float | None:
        """sup ‖F‖₂, or None when F is unbounded."""
        ...

    def force(self, at: Placed, dx: Array) -> Array:
        """F, shape (n,)."""
        ...
