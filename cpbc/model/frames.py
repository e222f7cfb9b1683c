"""A frame's placement and Jacobian at one state, and bounds on its Jacobian over every
configuration (TASKSPACE §2.2: the bounded task springs keep the torque bound (7.32)).

The Jacobian is Pinocchio's ``LOCAL_WORLD_ALIGNED`` one, [v; ω] of the frame's origin in
world axes, taken with respect to the controller coordinates x = T q (∂/∂x = ∂/∂q T⁻¹).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from cpbc.arrays import Array


def cross3(a: Array, b: Array) -> Array:
    """a × b of two 3-vectors, written out (numpy.cross costs tens of µs a call)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                     a[0] * b[1] - a[1] * b[0]])


def offset_jacobian(linear: Array, angular: Array, r: Array) -> Array:
    """∂p/∂x of a point at r (world axes) from a frame's origin: v_p = v_o + ω × r."""
    skew = np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])
    return linear - skew @ angular


class FrameKinematics(NamedTuple):
    """One frame at one state, in controller coordinates (a tuple: built every control
    step, where a frozen dataclass costs several times more to make).

    Attributes:
        placement: the frame's placement [R p; 0 1] in the world, shape (4, 4); its
            ``position`` p [m] and ``rotation`` R are views of it.
        jacobian: [∂p/∂x; J_ω], shape (6, n): the origin's velocity and the frame's angular
            velocity (world axes) per unit ẋ.
    """

    placement: Array
    jacobian: Array

    @property
    def position(self) -> Array:
        """The frame's origin in the world, shape (3,) [m]."""
        return self.placement[:3, 3]

    @property
    def rotation(self) -> Array:
        """R, the frame's axes in the world, shape (3, 3)."""
        return self.placement[:3, :3]

    @property
    def linear(self) -> Array:
        """J_v = ∂p/∂x, shape (3, n)."""
        return self.jacobian[:3]

    @property
    def angular(self) -> Array:
        """J_ω, shape (3, n): ω = J_ω ẋ in world axes."""
        return self.jacobian[3:]

    def point(self, offset: Array | None) -> tuple[Array, Array]:
        """Position (3,) and ∂p/∂x (3, n) of the point at ``offset`` (frame axes) in the frame."""
        if offset is None:
            return self.position, self.linear
        r = self.rotation @ offset
        return self.position + r, offset_jacobian(self.linear, self.angular, r)


def _column_bounds(model: pin.Model, frame_id: int, offset: Array | None
                   ) -> tuple[Array, Array]:
    """Bounds over all configurations on ‖∂p/∂q_i‖ and ‖∂ω/∂q̇_i‖ for every joint i.

    A revolute joint's column is z_i × (p − o_i), whose length is at most |p − o_i|: the sum of
    the fixed joint-to-joint offsets from joint i to the frame, the frame's own offset and the
    point's, plus the travel of every prismatic joint in between (its position limit, inf when
    unlimited). A prismatic column is its unit axis (length 1, no rotation).
    """
    frame = model.frames[frame_id]
    reach = float(np.linalg.norm(frame.placement.translation))
    if offset is not None:
        reach += float(np.linalg.norm(offset))
    linear, angular = np.zeros(model.nv), np.zeros(model.nv)
    joint = frame.parentJoint
    while joint > 0:
        j = model.joints[joint]
        prismatic = not j.shortname().startswith("JointModelR")
        idx = j.idx_v
        linear[idx] = 1.0 if prismatic else reach
        angular[idx] = 0.0 if prismatic else 1.0
        if prismatic:
            lo, hi = model.lowerPositionLimit[j.idx_q], model.upperPositionLimit[j.idx_q]
            travel = max(abs(lo), abs(hi))
            reach += travel if math.isfinite(travel) and travel < 1e10 else math.inf
        reach += float(np.linalg.norm(model.jointPlacements[joint].translation))
        joint = model.parents[joint]
    return linear, angular


def jacobian_bounds(model: pin.Model, t_inv: Array, frame_id: int,
                    offset: Array | None = None) -> tuple[float, float]:
    """Upper bounds on ‖J_v(x)‖₂ and ‖J_ω(x)‖₂ over every configuration, in controller
    coordinates (J_x = J_q T⁻¹): with c_i ≥ ‖column i of J_q‖, column j of J_x is at most
    Σ_i c_i |T⁻¹_ij| long, and the spectral norm is at most the Frobenius norm."""
    linear, angular = _column_bounds(model, frame_id, offset)
    mix = np.abs(t_inv)
    return float(np.linalg.norm(mix.T @ linear)), float(np.linalg.norm(mix.T @ angular))
