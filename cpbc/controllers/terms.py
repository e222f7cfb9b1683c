"""The damping term of the laws (Chapters 6 and 7); their potentials are in
``cpbc.controllers.potentials``."""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

import numpy as np

from cpbc.arrays import Array

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
        return self.kd * dx


class TanhDamping:
    """K_D tanh(Γ ẋ) (eq. 7.17), bounded by K_D."""

    def __init__(self, kd: Array, gamma: Array) -> None:
        self.kd = kd
        self.gamma = gamma

    def force(self, dx: Array) -> Array:
        return self.kd * np.tanh(self.gamma * dx)


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
