"""Constraint interfaces (Assumptions 6.4 and 6.6).

A constraint object may describe several scalar constraints at once (one per joint, say),
so that the hot path is vectorised; ``names`` has one entry per scalar constraint.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np
from numpy.typing import NDArray

from cpbc.model.robot_model import DynamicsTerms

Array = NDArray[np.float64]


class ConfigurationConstraint(ABC):
    """φ_i(x) = h_i(x) − Δ_i > 0 (eq. 6.16), with gradient ∇φ_i(x)."""

    names: tuple[str, ...]
    # whether barrier_terms returns φ itself (a localised barrier returns a reshaped φ̃)
    barrier_is_margin: bool = True

    @abstractmethod
    def value(self, x: Array) -> Array:
        """φ(x), shape (k,)."""

    @abstractmethod
    def gradient(self, x: Array) -> Array:
        """∂φ/∂x, shape (k, n)."""

    def evaluate(self, x: Array) -> tuple[Array, Array]:
        """φ(x) and ∂φ/∂x together (subclasses share kinematics here)."""
        return self.value(x), self.gradient(x)

    def barrier_terms(self, x: Array) -> tuple[Array, Array]:
        """φ(x) and Σ_i ∇φ_i/φ_i, shape (n,): what the laws need (DESIGN §3).

        Outside S (some φ_i ≤ 0) the second value is meaningless; callers check φ first.
        Subclasses override this with a cheaper closed form.
        """
        phi, grad = self.evaluate(x)
        return phi, (1.0 / phi) @ grad

    def barrier_terms_and_value(self, x: Array) -> tuple[Array, Array, Array]:
        """``barrier_terms(x)`` and ``value(x)``; subclasses whose barrier is not the margin
        override this to get both from one pass."""
        phi, b = self.barrier_terms(x)
        return phi, b, phi if self.barrier_is_margin else self.value(x)

    def values_along(self, xs: Array) -> Array:
        """φ at each row of xs, shape (N, k); vectorised by subclasses where they can."""
        return np.array([self.value(x) for x in xs]).reshape(len(xs), len(self.names))


class VelocityConstraint(ABC):
    """ψ_j(x, ẋ) = Ω_j(x) − ½ ẋᵀ Q_j(x) ẋ > 0 with Q_j ⪰ 0 (eq. 6.17).

    ``needs_dynamics`` says whether the constraint reads D or C from the dynamics terms.
    """

    names: tuple[str, ...]
    needs_dynamics: bool = False

    @abstractmethod
    def value(self, x: Array, dx: Array, dyn: DynamicsTerms | None) -> Array:
        """ψ(x, ẋ), shape (k,)."""

    def values_along(self, xs: Array, dxs: Array) -> Array:
        """ψ at each sample, shape (N, k); vectorised by subclasses where they can."""
        out = [self.value(x, dx, None) for x, dx in zip(xs, dxs, strict=True)]
        return np.array(out).reshape(len(xs), len(self.names))

    @abstractmethod
    def weights(self, x: Array, dyn: DynamicsTerms | None) -> Array:
        """Q_j(x), shape (k, n, n)."""

    @abstractmethod
    def gradient(self, x: Array, dx: Array, dyn: DynamicsTerms | None) -> Array:
        """∂ψ/∂x at fixed ẋ, shape (k, n)."""

    def barrier_terms(
        self, x: Array, dx: Array, dyn: DynamicsTerms | None
    ) -> tuple[Array, Array, Array | None]:
        """ψ, Π = Σ Q_j/ψ_j (n, n) and b = Σ (∂ψ_j/∂x)/ψ_j (n,) — the log-barrier form of DESIGN §3.

        b may be None when it is identically zero (constant Q and Ω). Subclasses override
        this with a cheaper closed form.
        """
        psi = self.value(x, dx, dyn)
        inv = 1.0 / psi
        pi = np.einsum("k,kij->ij", inv, self.weights(x, dyn))
        b = self.gradient(x, dx, dyn).T @ inv
        return psi, pi, b
