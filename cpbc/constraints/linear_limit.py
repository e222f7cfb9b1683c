"""Two-sided limits on linear combinations of coordinates: joint and relative-joint limits."""

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
from cpbc.constraints.constraint_types import ConfigurationConstraint
from cpbc.constraints.margins import POSITION, MarginType, headroom, row_types
from cpbc.constraints.packing import Packed
from cpbc.errors import ParameterError
from cpbc.kernels.barriers import (
    LINEAR_CONSTANTS,
    linear_limit_motion,
    linear_limit_terms,
    pack_linear_limit,
)
from cpbc.model.robot_model import ArmState
from cpbc.spec.fields import Vector


class LinearLimit(ConfigurationConstraint):
    """lower_i < a_iᵀ x < upper_i, written as one smooth constraint per row:

        φ_i(x) = (a_iᵀx − lower_i)(upper_i − a_iᵀx) = w_i² − (a_iᵀx − c_i)²

    with centre c_i and half-width w_i. For a row of the identity this is the thesis's joint
    limit of Case 2 (eq. 6.50, up to the constant factor ½ that no law depends on); for
    a = (−1, 1) and bounds ±17π/18 it is the relative-joint limit φ₂ of Section 6.4.

    Args:
        rows: the a_i, shape (k, n).
        lower, upper: bounds, shape (k,), lower < upper.
        names: one per row.
    """

    stacks = True
    margin_type = POSITION

    def margins(self, values: Array) -> Array:
        """φ = w² − (aᵀx − c)² as w − |aᵀx − c| [rad or m]."""
        return headroom(values, self.half_width)

    def margin_types(self, lengths: Array | None = None) -> tuple[MarginType, ...]:
        return row_types(POSITION, self.rows, lengths)

    def __init__(
        self, rows: ArrayLike, lower: ArrayLike, upper: ArrayLike, names: Sequence[str]
    ) -> None:
        rows = np.atleast_2d(np.asarray(rows, dtype=float))
        lower = np.atleast_1d(np.asarray(lower, dtype=float))
        upper = np.atleast_1d(np.asarray(upper, dtype=float))
        k = rows.shape[0]
        if lower.shape != (k,) or upper.shape != (k,) or len(names) != k:
            wrong = "lower" if lower.shape != (k,) else "upper" if upper.shape != (k,) else "names"
            raise ParameterError(
                wrong, f"linear limit: rows {rows.shape}, lower {lower.shape}, upper {upper.shape} "
                f"and {len(names)} names do not agree"
            )
        for name, given in (("rows", rows), ("lower", lower), ("upper", upper)):
            if not np.all(np.isfinite(given)):
                raise ParameterError(name, f"linear limit {name} must be finite, got "
                                           f"{given.tolist()}")
        if np.any(lower >= upper):
            i = int(np.argmax(lower >= upper))
            raise ParameterError("upper", f"linear limit needs lower < upper on every row: "
                                          f"{names[i]} has lower {lower[i]}, upper {upper[i]}")
        self.rows = rows
        self.lower = lower
        self.upper = upper
        self.names = tuple(names)
        self.centre = 0.5 * (lower + upper)
        self.half_width = 0.5 * (upper - lower)
        for a in (self.rows, self.lower, self.upper, self.centre, self.half_width):
            a.setflags(write=False)
        # |∇φ_i| = |l_i + u_i − 2a_iᵀx| |a_i| ≤ 2w_i |a_i| where φ_i > 0 (gradient_bound)
        self._slope_bound = 2.0 * self.half_width[:, None] * np.abs(rows)
        self._slope_bound.setflags(write=False)
        self._packed = pack_linear_limit(rows, lower, upper)  # the kernel's tables
        self._constants = self._packed.floats[LINEAR_CONSTANTS]

    def value(self, x: Array) -> Array:
        return self._value_at(self.rows.dot(x))

    def _value_at(self, y: Array) -> Array:
        """φ = (y − l)(u − y) at the rows' values y = a x."""
        return (y - self.lower) * (self.upper - y)

    def barrier_terms(self, state: ArmState, margins: bool = False
                      ) -> tuple[Array, Array, Array | None]:
        """φ, Σ ∇φ_i/φ_i = Σ a_i (l_i + u_i − 2a_iᵀx)/φ_i and φ again
        (cpbc.kernels.barriers.linear_limit_terms)."""
        phi, b = np.empty(len(self.names)), np.empty(self.rows.shape[1])
        linear_limit_terms(self._constants, state.x, phi, b)
        return phi, b, phi

    def packed(self) -> Packed | None:
        """The kernel's constants, unless a subclass overrides ``barrier_terms``."""
        if type(self).barrier_terms is not LinearLimit.barrier_terms:
            return None
        return self._packed

    @classmethod
    def stacked(cls, parts: Sequence[ConfigurationConstraint]) -> LinearLimit:
        """All rows of ``parts`` as one LinearLimit (one product per step instead of one
        per constraint)."""
        limits = [p for p in parts if isinstance(p, LinearLimit)]
        return LinearLimit(np.vstack([p.rows for p in limits]),
                           np.concatenate([p.lower for p in limits]),
                           np.concatenate([p.upper for p in limits]),
                           [name for p in limits for name in p.names])

    def values_along(self, xs: Array) -> Array:
        return self._value_at(xs @ self.rows.T)

    def gradient(self, x: Array) -> Array:
        """∇φ = (l + u − 2aᵀx) a, row by row."""
        x = np.asarray(x, dtype=float)
        return self._rows_at(x, x)[1]  # (its curvature, along x, unread)

    def gradient_at(self, state: ArmState) -> Array:
        return self._rows_at(state.x, state.dx)[1]

    def motion_terms(self, state: ArmState) -> tuple[Array, Array, Array]:
        """φ, ∇φ and ẋᵀ∇²φ ẋ in one compiled call (the stopping test's rows, read by the
        aimed brake at every period it is held)."""
        return self._rows_at(state.x, state.dx)

    def _rows_at(self, x: Array, dx: Array) -> tuple[Array, Array, Array]:
        """φ, ∇φ and ẋᵀ∇²φ ẋ at (x, ẋ) (cpbc.kernels.barriers.linear_limit_motion)."""
        k, n = self.rows.shape
        phi, grad, curvature = np.empty(k), np.empty((k, n)), np.empty(k)
        linear_limit_motion(self._constants, x, dx, phi, grad, curvature)
        return phi, grad, curvature

    def gradient_bound(self) -> Array | None:
        """2w_i |a_i|: |∇φ_i| = |l_i + u_i − 2a_iᵀx| |a_i| inside the limits."""
        return self._slope_bound

    def curvature(self, x: Array, dx: Array) -> Array:
        """ẋᵀ∇²φ ẋ = −2 (aᵀẋ)²: the product form loses margin faster than it approaches."""
        return self._rows_at(np.asarray(x, dtype=float), np.asarray(dx, dtype=float))[2]


def joint_position_limit(
    lower: ArrayLike, upper: ArrayLike, joint_names: Sequence[str],
    joints: Sequence[int] | None = None
) -> LinearLimit:
    """Asymmetric joint position limits lower_i < x_i < upper_i on the given joints.

    Args:
        lower, upper: bounds of the selected joints [rad or m].
        joint_names: names of all n coordinates (for labels).
        joints: indices of the limited joints; all when omitted.
    """
    n = len(joint_names)
    idx = list(range(n)) if joints is None else list(joints)
    rows = np.eye(n)[idx]
    return LinearLimit(rows, lower, upper, [f"position[{joint_names[i]}]" for i in idx])


# -- the scenario's ``type: joint_position_limit`` and ``type: linear_limit`` ----------------
class JointPositionLimitSpec(ConstraintEntrySpec):
    type: Literal["joint_position_limit"] = Field(
        description=(
            "lower < x_i < upper on coordinates, φ = (x − l)(u − x)"))
    name: str = Field(
        default="joint_position_limit", description=(
            "unique name, used by controllers' constraints lists and in the summary"))
    joints: list[str] | None = Field(
        default=None, description=(
            "the constrained coordinates by joint name; all when omitted"))
    lower: Vector | FromModel = Field(
        description=(
            "lower bounds [rad or m], or from_model (the model's joint ranges)"))
    upper: Vector | FromModel = Field(
        description=(
            "upper bounds [rad or m], or from_model (the model's joint ranges)"))


def build_joint_position_limit(spec: JointPositionLimitSpec,
                               given: ConstraintInputs) -> LinearLimit:
    idx = given.joints(spec.joints)
    return joint_position_limit(given.limit(spec.lower, "position", 0, idx, "lower"),
                                given.limit(spec.upper, "position", 1, idx, "upper"),
                                given.names, idx)


class LinearLimitSpec(ConstraintEntrySpec):
    type: Literal["linear_limit"] = Field(
        description=(
            "lower < aᵀx < upper for each row a (the thesis's |θ2 − θ1| < 17π/18)"))
    name: str = Field(
        default="linear_limit", description=(
            "unique name, used by controllers' constraints lists and in the summary"))
    coefficients: list[Vector] = Field(description="the rows a, one per limit")
    lower: Vector = Field(description="lower bound per row")
    upper: Vector = Field(description="upper bound per row")


def build_linear_limit(spec: LinearLimitSpec, given: ConstraintInputs) -> LinearLimit:
    rows = given.rows(spec.coefficients)
    k = rows.shape[0]
    return LinearLimit(rows, given.vector(spec.lower, k, "lower"),
                       given.vector(spec.upper, k, "upper"), row_labels(spec.name, k))


KINDS = (
    ConstraintKind(JointPositionLimitSpec, build_joint_position_limit, LinearLimit,
                   {"joint_position_limit": {"lower": [-3, -3], "upper": [3, 3]}}),
    ConstraintKind(LinearLimitSpec, build_linear_limit, LinearLimit,
                   {"linear_limit": {"coefficients": [[-1, 1]], "lower": [-3], "upper": [3]}}),
)
