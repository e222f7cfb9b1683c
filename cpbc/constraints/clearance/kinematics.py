"""Points fixed on the arm's links, read from Pinocchio in one call.

``Kinematics`` is the base of ``Clearance``: the attributes every part of it reads, the
columns that give a point fixed on a link from Pinocchio's static regressor Y, the joint
supports of each primitive, and the rows n̂ᵀ J(p) of a point's Jacobian from the joint
Jacobians.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from cpbc.arrays import Array
from cpbc.constraints.clearance.tables import CROSS
from cpbc.constraints.covering import LinkPrimitive
from cpbc.constraints.geometry import Obstacle
from cpbc.errors import CpbcError
from cpbc.model.robot_model import RobotModel

# the joints that turn (move) a link about (along) one axis, by Pinocchio's short names
_REVOLUTE = frozenset({"JointModelRX", "JointModelRY", "JointModelRZ",
                       "JointModelRevoluteUnaligned"})
_PRISMATIC = frozenset({"JointModelPX", "JointModelPY", "JointModelPZ",
                        "JointModelPrismaticUnaligned"})


class Kinematics:
    """What the parts of ``Clearance`` share: its settings, the robot's Pinocchio model and
    data, and points fixed on links as columns over the static regressor."""

    names: tuple[str, ...]
    model: RobotModel
    primitives: tuple[LinkPrimitive, ...]
    obstacles: tuple[Obstacle, ...]
    margin: float
    influence: float | None
    self_pairs: tuple[tuple[str, str], ...]
    _pin: pin.Model
    _data: pin.Data  # its own, for evaluations away from the per-step state
    _n: int
    _identity: bool
    _t_inv: Array
    _nj: int  # joints (without the universe)
    _scale: float  # Pinocchio's static regressor times this is the joint placements
    _supports: Array  # (njoints, n) 1 where joint k moves joint j's link
    _joint_supports: Array  # (n, n) 1 where coordinate i moves coordinate k's link (row k)
    _joint: list[int]  # each primitive's parent joint
    _local: list[tuple[Array, Array]]  # each primitive's ends in its joint's frame

    def _setup_kinematics(self) -> None:
        """Points fixed on links as columns over Pinocchio's static regressor.

        ``computeStaticRegressor`` returns, in one call, Y = [t_1 R_1 … t_n R_n]/M (3 × 4n):
        every joint placement, divided by the total mass M. A point l fixed in joint j's frame
        is then at M·Y[:, 4(j−1):4j] @ [1, l]: Y times a constant column.
        """
        pm = self._pin
        self._nj = pm.njoints - 1
        self._scale = self.model.regressor_scale()
        self._supports = self.model.joint_supports()
        self._joint_supports = self.model.coordinate_supports()
        self._joint = []
        self._local = []
        for p in self.primitives:
            frame = pm.frames[self.model.frame_id(p.frame)]
            if frame.parentJoint == 0:
                raise CpbcError(
                    f"primitive '{p.name}' is on '{p.frame}', which is welded to the world: "
                    "its clearance cannot change; leave it out"
                )
            self._joint.append(frame.parentJoint)
            self._local.append((frame.placement.act(p.start), frame.placement.act(p.end)))

    def _column(self, i: int, end: int | None) -> Array:
        """The column giving primitive i's start (0), end (1) or midpoint (None) from Y."""
        a, b = self._local[i]
        local = 0.5 * (a + b) if end is None else (a if end == 0 else b)
        j = self._joint[i]
        col = np.zeros(4 * self._nj)
        col[4 * (j - 1)] = self._scale
        col[4 * (j - 1) + 1: 4 * j] = self._scale * local
        return col

    def _columns(self, prims: Sequence[int], end: int | None) -> Array:
        return np.ascontiguousarray(np.column_stack([self._column(i, end) for i in prims]))

    def _reach(self, prims: Sequence[int]) -> Array:
        """(len(prims), n): for the first point p of each primitive (a sphere's centre) and
        each coordinate k, a bound on |∂p/∂q_k| over every configuration, so that
        ‖p(q') − p(q)‖ ≤ Σ_k reach_k |q'_k − q_k| along the segment from q to q'.

        A revolute joint k turns p about its axis a_k through its origin o_k,
        |∂p/∂q_k| ≤ |a_k| ‖p − o_k‖, and ‖p − o_k‖ is at most the chain of fixed offsets
        from o_k to p (the origins of the joints in between, then p in its joint's frame)
        whatever the configuration. A prismatic joint moves p by |a_k| per unit; the joints
        above it (whose chain it stretches) and any other kind of joint get no bound (∞)."""
        pm = self._pin
        out = np.zeros((len(prims), self._n))
        for row, i in enumerate(prims):
            chain, j = float(np.linalg.norm(self._local[i][0])), self._joint[i]
            while j > 0:
                joint = pm.joints[j]
                kind = joint.shortname()
                size = float(np.linalg.norm(joint.extract().axis)) if kind.endswith(
                    "Unaligned") else 1.0
                if kind in _REVOLUTE:
                    out[row, joint.idx_v] = size * chain
                    chain += float(np.linalg.norm(pm.jointPlacements[j].translation))
                elif kind in _PRISMATIC:
                    out[row, joint.idx_v] = size
                    chain = np.inf
                else:
                    out[row, joint.idx_v:joint.idx_v + joint.nv] = np.inf
                    chain = np.inf
                j = pm.parents[j]
        return out

    def _masks(self, prims: Sequence[int]) -> Array:
        return self._supports[[self._joint[i] for i in prims]]

    def _q(self, x: Array) -> Array:
        return x if self._identity else self._t_inv @ x

    def _regressor(self, q: Array) -> Array:
        """Y (3, 4n): every joint placement, scaled, in one Pinocchio call."""
        return pin.computeStaticRegressor(self._pin, self._data, q)

    def _jacobians(self, q: Array) -> Array:
        """Pinocchio's world joint Jacobians J = [v; ω] (6, n)."""
        pin.computeJointJacobians(self._pin, self._data, q)
        return self._data.J

    def _rows_times_jacobians(self, jac: Array, points: Array, normals: Array, masks: Array
                              ) -> Array:
        """Rows n_rᵀ J(p_r) with J(p) the Jacobian of a point fixed on its link, shape (r, n),
        joint coordinates, from the joint Jacobians ``jac`` (6, n) at the configuration."""
        outer = (points[:, :, None] * normals[:, None, :]).reshape(-1, 9)
        return (normals @ jac[:3] + outer @ (CROSS @ jac[3:])) * masks
