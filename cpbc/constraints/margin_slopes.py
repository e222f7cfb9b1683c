"""How far each margin of a constraint set moves for a small error of the state: the slopes
every error the safeguard holds reads (cpbc.controllers.safeguard.model_error: the model's,
the measurement's, the plant friction's over a rollout)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.kernels.margin_losses import margin_losses
from cpbc.model.robot_model import ArmState


@dataclass(frozen=True, eq=False)
class MarginSlopes:
    """How far each margin of a constraint set moves for a small error of the state, at the
    per-step state, read once a step for every error the guard holds (the model's and the
    measurement's): ∂φ_i/∂x of each configuration margin, and of each velocity margin
    ψ_k = ω_k − ½ẋᵀΠ_k ẋ, Π_k and ẋ (``VelocityConstraint.weights``: r rᵀ for a rate, D for
    the kinetic energy); :meth:`losses` takes their sizes |∇φ_i|, |Π_k ẋ| and |Π_k|.

    Attributes:
        configuration: ∇φ_i rows, shape (number of φ_i, n).
        weights: Π_k, shape (number of ψ_k, n, n).
        rates: ẋ, shape (n,).
    """

    configuration: Array
    weights: Array
    rates: Array

    @classmethod
    def at(cls, constraints: ConstraintSet, state: ArmState) -> MarginSlopes:
        """The slopes at the per-step state."""
        return cls._of(constraints, state, constraints.configuration_gradients(state))

    @classmethod
    def bounding(cls, constraints: ConstraintSet, state: ArmState) -> MarginSlopes:
        """The slopes with each configuration gradient's bound where its kind knows one
        (ConstraintSet.configuration_gradient_bounds): :meth:`losses` then bounds every
        margin's loss from above, without the state's kinematics for those kinds."""
        return cls._of(constraints, state, constraints.configuration_gradient_bounds(state))

    @classmethod
    def _of(cls, constraints: ConstraintSet, state: ArmState, config: Array) -> MarginSlopes:
        n = constraints.n
        weights = [c.weights(state.x, state) for c in constraints.velocity]  # (k, n, n) each
        if not weights:
            return cls(config, np.zeros((0, n, n)), state.dx)
        return cls(config, weights[0] if len(weights) == 1 else np.concatenate(weights),
                   state.dx)

    def losses(self, end_shift: Array, mid_shift: Array, rate_shift: Array
               ) -> tuple[Array, Array]:
        """What each margin can lose to a position off by at most ``end_shift`` at the
        period's end and ``mid_shift`` at mid-period, per coordinate, and a rate off by at
        most ``rate_shift``: Σ_j |∂φ_i/∂x_j| s_j for a configuration margin, and
        Σ_j |(Π_k ẋ)_j| w_j + ½ wᵀ|Π_k|w for a velocity margin (exact for a constant Π_k;
        cpbc.kernels.margin_losses.margin_losses). (At the period's end, every margin in
        the order of ``names``; at mid-period, the configuration ones.)"""
        m = len(self.configuration)
        end, mid = np.empty(m + len(self.weights)), np.empty(m)
        margin_losses(self.configuration, self.weights, self.rates, end_shift, mid_shift,
                      rate_shift, end, mid)
        return end, mid
