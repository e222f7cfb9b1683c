"""An arm's kinematic chain as the tables of the compiled joint placements
(cpbc.kernels.joint_placements), read from its Pinocchio model: the guard's test asks for the
placements at many configurations a step, which Pinocchio gives one configuration a call."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from cpbc.arrays import Array
from cpbc.kernels.joint_placements import (
    PRISMATIC,
    REVOLUTE,
    REVOLUTE_X,
    REVOLUTE_Y,
    REVOLUTE_Z,
    joint_placements,
)
from cpbc.kernels.plan_tables import Ints

# Pinocchio's joint kinds the chain's table holds, and the axis of those that fix it
_KINDS = {"JointModelRX": (REVOLUTE_X, (1.0, 0.0, 0.0)),
          "JointModelRY": (REVOLUTE_Y, (0.0, 1.0, 0.0)),
          "JointModelRZ": (REVOLUTE_Z, (0.0, 0.0, 1.0)),
          "JointModelRevoluteUnaligned": (REVOLUTE, None),
          "JointModelPX": (PRISMATIC, (1.0, 0.0, 0.0)),
          "JointModelPY": (PRISMATIC, (0.0, 1.0, 0.0)),
          "JointModelPZ": (PRISMATIC, (0.0, 0.0, 1.0)),
          "JointModelPrismaticUnaligned": (PRISMATIC, None)}


@dataclass(frozen=True, eq=False)
class JointChain:
    """The chain's tables, one row per joint in Pinocchio's order (parents first).

    Attributes:
        parents: each joint's parent (1-based, 0 the world).
        kinds: each joint's kind (cpbc.kernels.joint_placements).
        axes: each joint's unit axis, shape (m, 3).
        rotations, translations: each joint's fixed placement in its parent, (m, 3, 3) and
            (m, 3).
        coordinates: each joint's coordinate in q.
        scale: s of the layout [t_1 R_1 … t_m R_m] / s (RobotModel.regressor_scale).
    """

    parents: Ints
    kinds: Ints
    axes: Array
    rotations: Array
    translations: Array
    coordinates: Ints
    scale: float

    @classmethod
    def of(cls, model: pin.Model, scale: float) -> JointChain | None:
        """The chain of ``model`` with the regressor's ``scale``, or None where a joint is of
        a kind the table does not hold (its placements are then Pinocchio's)."""
        kinds, axes = [], []
        for j in range(1, model.njoints):
            joint = model.joints[j]
            found = _KINDS.get(joint.shortname())
            if found is None or joint.nq != 1:
                return None
            kind, axis = found
            kinds.append(kind)
            axes.append(joint.extract().axis if axis is None else axis)
        placements = [model.jointPlacements[j] for j in range(1, model.njoints)]
        return cls(np.array([model.parents[j] for j in range(1, model.njoints)], dtype=np.int64),
                   np.array(kinds, dtype=np.int64), np.array(axes, dtype=float).reshape(-1, 3),
                   np.array([p.rotation for p in placements]).reshape(-1, 3, 3),
                   np.array([p.translation for p in placements]).reshape(-1, 3),
                   np.array([model.joints[j].idx_q for j in range(1, model.njoints)],
                            dtype=np.int64), float(scale))

    def placements(self, rows: Array) -> Array:
        """The joint placements at each row of ``rows`` (joint coordinates), shape
        (rows, 3, 4m): Pinocchio's static regressor at each, to rounding."""
        out = np.empty((len(rows), 3, 4 * len(self.parents)))
        joint_placements(self.parents, self.kinds, self.axes, self.rotations,
                         self.translations, self.coordinates, self.scale,
                         np.ascontiguousarray(rows, dtype=float), out)
        return out
