"""What an acceleration error can take off a constraint set's margins over a time: the
model's error held as a disturbance (cpbc.controllers.safeguard.model_error: over one control
period by the guard's floors, over a brake's rollout by the rescue's checks)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.model.robot_model import ArmState


@dataclass(frozen=True, eq=False)
class ErrorReach:
    """What an acceleration error |d_j| ≤ ā_j can take off each margin of a constraint set
    over a time t from a state (cpbc.controllers.safeguard.model_error's docstring, t in
    place of the period h): c t² Σ_j |∂φ_i/∂x_j|
    ā_j from a configuration margin (c = ½ in continuous time), t Σ_j |(Π_k ẋ)_j| ā_j +
    ½ t² āᵀ|Π_k|ā from a velocity margin, with ∇φ and Π_k ẋ read at the state.

    Attributes:
        configuration: Σ_j |∂φ_i/∂x_j| ā_j per configuration margin.
        push: Σ_j |(Π_k ẋ)_j| ā_j per velocity margin.
        drift: ½ āᵀ|Π_k|ā per velocity margin.
    """

    configuration: Array
    push: Array
    drift: Array

    @classmethod
    def at(cls, constraints: ConstraintSet, state: ArmState, bound: Array) -> ErrorReach:
        config = np.abs(constraints.configuration_gradients(state)) @ bound
        push, drift = [], []
        for c in constraints.velocity:
            weights = c.weights(state.x, state)  # (k, n, n)
            push.append(np.abs(weights @ state.dx) @ bound)
            drift.append(0.5 * np.einsum("kij,i,j->k", np.abs(weights), bound, bound))
        empty = np.zeros(0)
        return cls(config, np.concatenate(push) if push else empty,
                   np.concatenate(drift) if drift else empty)

    def losses(self, t: float, travel: float = 0.5) -> Array:
        """Every margin's loss after t [s], in the order of the set's names (``travel``: c
        of the configuration margins' t² term)."""
        return np.concatenate((travel * t * t * self.configuration,
                               t * self.push + t * t * self.drift))
