"""The joint placements of an arm at many configurations in one call: forward kinematics of a
chain of revolute and prismatic joints, written into the static regressor's layout
[t_1 R_1 … t_m R_m] / s (s the regressor's scale, RobotModel.regressor_scale), what
Pinocchio's computeStaticRegressor gives for one configuration a call.

The guard's test asks for the placements at every configuration of a prediction whose sphere
clearances its bounds do not settle (cpbc.controllers.safeguard.predicted_margins): 38
configurations at the median of a step it acts in on the Panda under a rate limit (66 at p90),
~0.8 µs each through Pinocchio's Python binding (a call, a new array, a copy), 32 µs a step.
Here a configuration costs ~0.5 µs, most of it each joint's sine and cosine (20 of them: 11
µs against Pinocchio's 20). The chain's tables are written and read by
:class:`cpbc.model.joint_chain.JointChain`.

For joint j (its parent p_j, 0 the world): oM_j = oM_{p_j} · M_j · X_j(q), M_j the joint's
fixed placement in its parent, X_j(q) its motion: a rotation by q about its axis (revolute)
or a translation by q along it (prismatic).
"""

from __future__ import annotations

import math

import numpy as np

from cpbc.arrays import Array
from cpbc.kernels import inner, kernel
from cpbc.kernels.plan_tables import Ints

#: the joint kinds of the chain's table: a rotation about x, y or z (the rotation's 2 × 2
#: block written exactly, as Pinocchio's RX, RY, RZ), about any unit axis, a translation
REVOLUTE_X, REVOLUTE_Y, REVOLUTE_Z, REVOLUTE, PRISMATIC = 0, 1, 2, 3, 4


@inner("void(int64, float64, float64, float64, float64, float64[:, :])")
def _motion(kind: int, x: float, y: float, z: float, q: float, out: Array) -> None:
    """X_j(q)'s rotation about the unit axis (x, y, z) into ``out`` (the identity for a
    prismatic joint)."""
    for i in range(3):
        for k in range(3):
            out[i, k] = 1.0 if i == k else 0.0
    if kind == PRISMATIC:
        return
    c, s = math.cos(q), math.sin(q)
    if kind == REVOLUTE:  # Rodrigues: c I + s [a]× + (1 − c) a aᵀ
        v = 1.0 - c
        out[0, 0], out[0, 1], out[0, 2] = c + v * x * x, v * x * y - s * z, v * x * z + s * y
        out[1, 0], out[1, 1], out[1, 2] = v * x * y + s * z, c + v * y * y, v * y * z - s * x
        out[2, 0], out[2, 1], out[2, 2] = v * x * z - s * y, v * y * z + s * x, c + v * z * z
        return
    a, b = (1, 2) if kind == REVOLUTE_X else (2, 0) if kind == REVOLUTE_Y else (0, 1)
    out[a, a], out[a, b], out[b, a], out[b, b] = c, -s, s, c


@kernel("void(int64[:], int64[:], float64[:, :], float64[:, :, :], float64[:, :], int64[:],"
        " float64, float64[:, :], float64[:, :, :])")
def joint_placements(parents: Ints, kinds: Ints, axes: Array, rotations: Array,
                     translations: Array, coordinates: Ints, scale: float, rows: Array,
                     out: Array) -> None:
    """Every joint's placement at each row of ``rows`` (joint coordinates) into ``out``,
    shape (rows, 3, 4m): row r's block j is [t_j R_j] / ``scale``. Joint j (0-based) has
    parent ``parents[j]`` (1-based, 0 the world), kind ``kinds[j]``, unit axis ``axes[j]``,
    fixed placement (``rotations[j]``, ``translations[j]``) in its parent and coordinate
    ``coordinates[j]``; a parent comes before its children. Indexed, not sliced: a slice
    in the loop costs a reference count, more than its joint's arithmetic."""
    m = parents.shape[0]
    world_r = np.zeros((m + 1, 3, 3))
    world_t = np.zeros((m + 1, 3))
    for i in range(3):
        world_r[0, i, i] = 1.0
    move = np.empty((3, 3))
    local_r = np.empty((3, 3))
    local_t = np.empty(3)
    inverse = 1.0 / scale
    for r in range(rows.shape[0]):
        for j in range(m):
            q = rows[r, coordinates[j]]
            kind = kinds[j]
            _motion(kind, axes[j, 0], axes[j, 1], axes[j, 2], q, move)
            for i in range(3):  # M_j · X_j(q)
                local_t[i] = translations[j, i]
                if kind == PRISMATIC:
                    for k in range(3):
                        local_t[i] += rotations[j, i, k] * (axes[j, k] * q)
                for k in range(3):
                    local_r[i, k] = (rotations[j, i, 0] * move[0, k]
                                     + rotations[j, i, 1] * move[1, k]
                                     + rotations[j, i, 2] * move[2, k])
            p = parents[j]
            for i in range(3):  # oM_p · (M_j X_j)
                world_t[j + 1, i] = (world_t[p, i] + world_r[p, i, 0] * local_t[0]
                                     + world_r[p, i, 1] * local_t[1]
                                     + world_r[p, i, 2] * local_t[2])
                for k in range(3):
                    world_r[j + 1, i, k] = (world_r[p, i, 0] * local_r[0, k]
                                            + world_r[p, i, 1] * local_r[1, k]
                                            + world_r[p, i, 2] * local_r[2, k])
            column = 4 * j
            for i in range(3):
                out[r, i, column] = world_t[j + 1, i] * inverse
                for k in range(3):
                    out[r, i, column + 1 + k] = world_r[j + 1, i, k] * inverse
