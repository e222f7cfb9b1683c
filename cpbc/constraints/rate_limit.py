"""Symmetric bounds on joint rates, or on linear combinations of them (Remark 6.7, eq. 7.9)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np
from pydantic import Field

from cpbc.arrays import Array, ArrayLike
from cpbc.constraints.constraint_kind import (
    ConstraintEntrySpec,
    ConstraintInputs,
    ConstraintKind,
    FromModel,
    row_labels,
)
from cpbc.constraints.constraint_types import VelocityConstraint
from cpbc.constraints.margins import RATE, MarginType, headroom, row_types
from cpbc.constraints.packing import Packed
from cpbc.errors import ParameterError
from cpbc.kernels.barriers import RATE_CONSTANTS, pack_rate_limit, rate_limit_terms
from cpbc.model.robot_model import ArmState
from cpbc.spec.fields import Positive, Vector


class RateLimit(VelocityConstraint):
    """|a_jᵀ ẋ| < B_j, written as ψ_j = ½(B_j² − (a_jᵀẋ)²) with Q_j = a_j a_jᵀ, Ω_j = B_j²/2.

    For a_j = e_j this is the per-joint bound of Remark 6.7 and eq. 7.9. Q and Ω are constant,
    so ∂ψ/∂x = 0 and the barrier terms are Π = Aᵀ diag(1/ψ) A, b = 0.

    Args:
        rows: the a_j, shape (k, n).
        bounds: B_j > 0, shape (k,) [rad/s].
        names: one per row.
    """

    stacks = True
    margin_type = RATE

    def margins(self, values: Array) -> Array:
        """ψ = ½(B² − (aᵀẋ)²) as B − |aᵀẋ| [rad/s or m/s]."""
        return headroom(2.0 * values, self.bounds)

    def margin_types(self, lengths: Array | None = None) -> tuple[MarginType, ...]:
        return row_types(RATE, self.rows, lengths)

    def __init__(self, rows: ArrayLike, bounds: ArrayLike, names: Sequence[str]) -> None:
        rows = np.atleast_2d(np.asarray(rows, dtype=float))
        bounds = np.atleast_1d(np.asarray(bounds, dtype=float))
        if bounds.shape != (rows.shape[0],) or len(names) != rows.shape[0]:
            raise ParameterError(
                "bounds" if len(names) == rows.shape[0] else "names",
                f"rate limit: {rows.shape[0]} rows, bounds of shape {bounds.shape} and "
                f"{len(names)} names do not agree")
        if not np.all(np.isfinite(bounds)) or np.any(bounds <= 0):
            raise ParameterError("bounds", f"rate limit bounds must be finite and > 0, got "
                                           f"{bounds.tolist()}")
        self.rows = rows
        self.bounds = bounds
        self.names = tuple(names)
        self._omega = 0.5 * bounds**2
        # A row of the identity needs no matrix product in the hot path.
        unit = (np.count_nonzero(rows, axis=1) == 1) & np.isclose(np.abs(rows).sum(axis=1), 1.0)
        self._joint_index = np.argmax(np.abs(rows), axis=1) if np.all(unit) else None
        if self._joint_index is not None and len(set(self._joint_index.tolist())) != len(bounds):
            raise ParameterError("rows", "rate limit: a joint is bounded twice in one constraint")
        self._weights = np.einsum("ki,kj->kij", rows, rows)
        for a in (self.rows, self.bounds, self._weights):
            a.setflags(write=False)
        self._packed = pack_rate_limit(rows, self._omega)  # the kernel's tables
        self._constants = self._packed.floats[RATE_CONSTANTS]

    @property
    def is_per_joint(self) -> bool:
        """True when every row bounds a single coordinate."""
        return self._joint_index is not None

    @property
    def joint_index(self) -> Array | None:
        """The coordinate each row bounds (per-joint limits), else None."""
        return self._joint_index

    def packed(self) -> Packed | None:
        """The kernel's constants, unless a subclass overrides ``barrier_terms``."""
        if type(self).barrier_terms is not RateLimit.barrier_terms:
            return None
        return self._packed

    @classmethod
    def stacked(cls, parts: Sequence[VelocityConstraint]) -> RateLimit:
        """All rows of ``parts`` as one RateLimit (CpbcError if a joint is bounded twice)."""
        limits = [p for p in parts if isinstance(p, RateLimit)]
        return RateLimit(np.vstack([p.rows for p in limits]),
                         np.concatenate([p.bounds for p in limits]),
                         [name for p in limits for name in p.names])

    def value(self, x: Array, dx: Array, state: ArmState | None = None) -> Array:
        y = dx[self._joint_index] if self._joint_index is not None else self.rows.dot(dx)
        return self._omega - 0.5 * y * y

    def values_along(self, xs: Array, dxs: Array) -> Array:
        y = dxs @ self.rows.T
        return self._omega - 0.5 * y * y

    def weights(self, x: Array, state: ArmState | None = None) -> Array:
        """Q_k = r_k r_kᵀ, constant (read-only, formed once)."""
        return self._weights

    def gradient(self, x: Array, dx: Array, state: ArmState | None = None) -> Array:
        return np.zeros((self.rows.shape[0], x.shape[0]))

    def barrier_terms(self, state: ArmState) -> tuple[Array, Array, Array | None]:
        """ψ, Π = Aᵀ diag(1/ψ) A and b = 0 (None) (cpbc.kernels.barriers.rate_limit_terms)."""
        n = self.rows.shape[1]
        psi, pi = np.empty(len(self.names)), np.empty((n, n))
        rate_limit_terms(self._constants, state.dx, psi, pi)
        return psi, pi, None


def joint_rate_limit(
    bounds: ArrayLike, joint_names: Sequence[str], joints: Sequence[int] | None = None
) -> RateLimit:
    """|ẋ_i| < B_i on the given joints (all when omitted)."""
    n = len(joint_names)
    idx = list(range(n)) if joints is None else list(joints)
    return RateLimit(np.eye(n)[idx], bounds, [f"rate[{joint_names[i]}]" for i in idx])


# -- the scenario's ``type: joint_rate_limit`` and ``type: rate_limit`` ----------------------
class JointRateLimitSpec(ConstraintEntrySpec):
    type: Literal["joint_rate_limit"] = Field(description="|ẋ_i| < B_i on coordinates")
    name: str = Field(
        default="joint_rate_limit", description=(
            "unique name, used by controllers' constraints lists and in the summary"))
    joints: list[str] | None = Field(
        default=None, description=(
            "the constrained coordinates by joint name; all when omitted"))
    bounds: list[Positive] | FromModel = Field(
        description=(
            "the rate bounds B_i [rad/s or m/s], or from_model (the URDF's velocity limits; "
            "on an arm with position-dependent ones, the fr3, at most the largest constant "
            "bound inside them on the scenario's joint range)"))
    # multiplies the bounds (e.g. 0.5 of the URDF's velocity limits)
    scale: Positive = Field(
        default=1.0, description=(
            "factor on the bounds (0.5: half the URDF's velocity limits)"))


def build_joint_rate_limit(spec: JointRateLimitSpec, given: ConstraintInputs) -> RateLimit:
    idx = given.joints(spec.joints)
    return joint_rate_limit(given.rate_bounds(spec.bounds, spec.scale, idx, "bounds"),
                            given.names, idx)


class RateLimitSpec(ConstraintEntrySpec):
    type: Literal["rate_limit"] = Field(description="|aᵀẋ| < B for each row a")
    name: str = Field(
        default="rate_limit", description=(
            "unique name, used by controllers' constraints lists and in the summary"))
    coefficients: list[Vector] = Field(description="the rows a, one per bound")
    bounds: list[Positive] = Field(description="the bound B per row")


def build_rate_limit(spec: RateLimitSpec, given: ConstraintInputs) -> RateLimit:
    rows = given.rows(spec.coefficients)
    k = rows.shape[0]
    return RateLimit(rows, given.vector(spec.bounds, k, "bounds"), row_labels(spec.name, k))


KINDS = (
    ConstraintKind(JointRateLimitSpec, build_joint_rate_limit, RateLimit,
                   {"joint_rate_limit": {"bounds": [2, 2]}}),
    ConstraintKind(RateLimitSpec, build_rate_limit, RateLimit,
                   {"rate_limit": {"coefficients": [[1, 1]], "bounds": [3]}}),
)
