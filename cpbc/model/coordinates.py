"""Linear changes of generalised coordinates x = T q (the controller's coordinates).

The thesis's planar arm (eq. 6.69) is written in absolute link angles θ while MuJoCo and
URDF joints are relative angles q. With θ = T q and T constant, the Euler–Lagrange
structure is kept:

    D_θ = T⁻ᵀ D_q T⁻¹,   C_θ = T⁻ᵀ C_q T⁻¹,   g_θ = T⁻ᵀ g_q,   τ_q = Tᵀ τ_θ
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from cpbc.arrays import Array
from cpbc.errors import ModelError


def _frozen(a: Array) -> Array:
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class LinearCoordinates:
    """Controller coordinates x = T q, with T constant and invertible.

    Args:
        matrix: T, shape (n, n).
        name: a label for summaries (e.g. ``"absolute"``).
    """

    matrix: Array
    name: str = "custom"
    inverse: Array = field(init=False, repr=False)
    # T = I: joint coordinates (read on every guarded step; settled once, here)
    is_identity: bool = field(init=False, repr=False)

    def __post_init__(self) -> None:
        t = np.asarray(self.matrix, dtype=float)
        if t.ndim != 2 or t.shape[0] != t.shape[1]:
            raise ModelError(f"coordinate matrix must be square, got shape {t.shape}")
        if not np.all(np.isfinite(t)) or np.linalg.cond(t) > 1e12:
            raise ModelError("coordinate matrix T must be invertible (condition number ≤ 1e12)")
        object.__setattr__(self, "matrix", _frozen(t))
        object.__setattr__(self, "inverse", _frozen(np.linalg.inv(t)))
        object.__setattr__(self, "is_identity", bool(np.array_equal(t, np.eye(t.shape[0]))))

    @classmethod
    def identity(cls, n: int) -> LinearCoordinates:
        return cls(np.eye(n), name="joint")

    @classmethod
    def absolute_link_angles(cls, n: int) -> LinearCoordinates:
        """θ_k = q_1 + … + q_k: absolute angle of link k for a planar serial chain."""
        return cls(np.tril(np.ones((n, n))), name="absolute")

    def from_joint(self, q: Array) -> Array:
        """x = T q (also for velocities)."""
        return self.matrix @ q

    def to_joint(self, x: Array) -> Array:
        """q = T⁻¹ x (also for velocities)."""
        return self.inverse @ x

    def torque_to_joint(self, tau_x: Array) -> Array:
        """τ_q = Tᵀ τ_x: joint torques that do the same work as τ_x."""
        return self.matrix.T @ tau_x

    def torque_from_joint(self, tau_q: Array) -> Array:
        """τ_x = T⁻ᵀ τ_q."""
        return self.inverse.T @ tau_q

    def matrix_from_joint(self, m_q: Array) -> Array:
        """T⁻ᵀ M T⁻¹ for an (n, n) matrix M of the joint coordinates (D, C, F_d)."""
        return self.inverse.T @ m_q @ self.inverse
