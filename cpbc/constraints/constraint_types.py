"""Constraint interfaces (Assumptions 6.4 and 6.6).

A constraint object may describe several scalar constraints at once (one per joint, say),
so that the hot path is vectorised; ``names`` has one entry per scalar constraint. The laws
read a constraint at the per-step state (:class:`cpbc.model.ArmState`) computed once per
control step; ``value`` and ``values_along`` evaluate it at any other configuration.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.margins import HasMargins
from cpbc.constraints.packing import Packed
from cpbc.model.robot_model import ArmState


class ConfigurationConstraint(HasMargins, ABC):
    """φ_i(x) = h_i(x) − Δ_i > 0 (eq. 6.16), with gradient ∇φ_i(x).

    Attributes:
        names: one per scalar constraint.
        needs_kinematics: whether ``barrier_terms`` reads the state's joint placements and
            Jacobians (``RobotModel.state(kinematics=True)``).
        frames: the frames whose kinematics ``barrier_terms`` reads from ``ArmState.frames``.
        motion_kinematics: whether ``motion_terms`` reads the state's joint Jacobians even
            where ``barrier_terms`` does not (``ConstraintSet.state(..., motion=True)``).
        margin_type: the type and unit of its margins, declared by each concrete class
            (cpbc.constraints.margins).
    """

    names: tuple[str, ...]
    needs_kinematics: bool = False
    motion_kinematics: bool = False
    frames: tuple[int, ...] = ()
    stacks: bool = False  # whether neighbours of this class are evaluated as one (stacked)

    @abstractmethod
    def value(self, x: Array) -> Array:
        """φ(x), shape (k,)."""

    @abstractmethod
    def gradient(self, x: Array) -> Array:
        """∂φ/∂x, shape (k, n)."""

    def evaluate(self, x: Array) -> tuple[Array, Array]:
        """φ(x) and ∂φ/∂x together (subclasses share kinematics here)."""
        return self.value(x), self.gradient(x)

    def barrier_terms(self, state: ArmState, margins: bool = False
                      ) -> tuple[Array, Array, Array | None]:
        """What the laws need (their log-barrier form): the barrier values φ̃ (k,) whose logs
        enter V, Σ_i ∇φ̃_i/φ̃_i, shape (n,), and — with ``margins`` — φ itself (None without).

        φ̃ = φ except for a localised barrier (Clearance with an influence distance). Outside
        S (some φ_i ≤ 0) the second value is meaningless; callers check the first.
        Subclasses override this with a cheaper closed form.
        """
        phi, grad = self.evaluate(state.x)
        return phi, (1.0 / phi) @ grad, phi

    def barrier_ratio(self, phi: Array) -> Array:
        """(dφ̃/dφ)/φ̃ at the margins ``phi``: what turns ∇φ_i into the law's ∇φ̃_i/φ̃_i;
        1/φ unless the law is given other functions φ̃ (a localised Clearance)."""
        return 1.0 / phi

    def values_along(self, xs: Array) -> Array:
        """φ at each row of xs, shape (N, k); vectorised by subclasses where they can."""
        return np.array([self.value(x) for x in xs]).reshape(len(xs), len(self.names))

    def curvature(self, x: Array, dx: Array) -> Array:
        """ẋᵀ ∇²φ_i ẋ, shape (k,), where a subclass knows it; zeros otherwise, which the
        stopping test (cpbc.constraints.stopping) then neglects."""
        return np.zeros(len(self.names))

    def gradient_at(self, state: ArmState) -> Array:
        """∂φ/∂x at the per-step state, shape (k, n): ``gradient`` at its x here; a kind
        whose gradient takes kinematics reads them from the state instead (Clearance)."""
        return self.gradient(state.x)

    def gradient_bound(self) -> Array | None:
        """B with |∂φ_i/∂x_j| ≤ B_ij at every configuration where φ_i > 0, shape (k, n),
        where the kind knows one that costs less than its gradient at a state (Clearance:
        its sphere pairs' reach; LinearLimit), else None. The safeguard's first test raises
        its floors for the model's error by it (MarginSlopes.bounding), and by the gradient
        only where that fails."""
        return None

    def motion_terms(self, state: ArmState) -> tuple[Array, Array, Array]:
        """φ, ∇φ and ẋᵀ∇²φ ẋ at the per-step state (what a filter on φ̈ reads, e.g. the
        CBF-QP peer's rows). Here from ``evaluate`` and ``curvature`` at (x, ẋ); a kind whose
        evaluation takes kinematics reads them from the state instead (Clearance,
        PointOutsideSphere)."""
        phi, grad = self.evaluate(state.x)
        return phi, grad, self.curvature(state.x, state.dx)

    @classmethod
    def stacked(cls, parts: Sequence[ConfigurationConstraint]) -> ConfigurationConstraint:
        """One constraint that evaluates ``parts`` (all of this class) together, with their
        names in order; classes with rows to stack override this."""
        if len(parts) != 1:
            raise TypeError(f"{cls.__name__} does not stack")
        return parts[0]

    def packed(self) -> Packed | None:
        """This constraint's share of its set's barrier kernel (its kind's ``pack_*``,
        beside its kernel; cpbc.kernels.plan_tables), or None: its ``barrier_terms`` is asked in
        Python (cpbc.constraints.python_terms). Kinds with a kernel override this."""
        return None


class VelocityConstraint(HasMargins, ABC):
    """ψ_j(x, ẋ) = Ω_j(x) − ½ ẋᵀ Q_j(x) ẋ > 0 with Q_j ⪰ 0 (eq. 6.17).

    ``needs_dynamics`` says whether the constraint reads D from the state; without a state
    (at a predicted configuration) such a constraint asks the model. ``needs_coriolis`` says
    whether ``barrier_terms`` reads the matrix C from the state
    (``RobotModel.state(coriolis=True)``). ``margin_type``: as for configuration constraints.
    """

    names: tuple[str, ...]
    needs_dynamics: bool = False
    needs_coriolis: bool = False
    stacks: bool = False  # whether neighbours of this class are evaluated as one (stacked)

    @abstractmethod
    def value(self, x: Array, dx: Array, state: ArmState | None = None) -> Array:
        """ψ(x, ẋ), shape (k,)."""

    def values_along(self, xs: Array, dxs: Array) -> Array:
        """ψ at each sample, shape (N, k); vectorised by subclasses where they can."""
        out = [self.value(x, dx) for x, dx in zip(xs, dxs, strict=True)]
        return np.array(out).reshape(len(xs), len(self.names))

    @abstractmethod
    def weights(self, x: Array, state: ArmState | None = None) -> Array:
        """Q_j(x), shape (k, n, n)."""

    @abstractmethod
    def gradient(self, x: Array, dx: Array, state: ArmState | None = None) -> Array:
        """∂ψ/∂x at fixed ẋ, shape (k, n)."""

    def barrier_terms(self, state: ArmState) -> tuple[Array, Array, Array | None]:
        """ψ, Π = Σ Q_j/ψ_j (n, n) and b = Σ (∂ψ_j/∂x)/ψ_j (n,) — the laws' log-barrier form.

        b may be None when it is identically zero (constant Q and Ω). Subclasses override
        this with a cheaper closed form.
        """
        x, dx = state.x, state.dx
        psi = self.value(x, dx, state)
        inv = 1.0 / psi
        pi = np.einsum("k,kij->ij", inv, self.weights(x, state))
        b = self.gradient(x, dx, state).T @ inv
        return psi, pi, b

    @classmethod
    def stacked(cls, parts: Sequence[VelocityConstraint]) -> VelocityConstraint:
        """One constraint that evaluates ``parts`` (all of this class) together."""
        if len(parts) != 1:
            raise TypeError(f"{cls.__name__} does not stack")
        return parts[0]

    def packed(self) -> Packed | None:
        """This constraint's share of its set's barrier kernel (its kind's ``pack_*``,
        beside its kernel; cpbc.kernels.plan_tables), or None: its ``barrier_terms`` is asked in
        Python (cpbc.constraints.python_terms). Kinds with a kernel override this."""
        return None
