"""Constant tables of the clearance's hot path.

The maps between the per-point force layout [vec(s ⊗ f); f] and Pinocchio's world joint
Jacobians J = [v; ω] (a cross product as a matrix, a wrench at a point), 0-d array
constants (numpy takes them faster than Python floats) and the index type. Read-only.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

# vec(p ⊗ n) @ CROSS = p × n
CROSS = np.zeros((9, 3))
for _i, _j, _k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
    CROSS[3 * _j + _k, _i] = 1.0
    CROSS[3 * _k + _j, _i] = -1.0
CROSS.setflags(write=False)

# vec((P; 1) ⊗ n) @ (WRENCH @ J) = nᵀ J_P for J = [v; ω] Pinocchio's world joint Jacobian
# (column k of J_P is v_k + ω_k × P): rows 3i + j hold CROSS @ ω, rows 9 + j hold v
WRENCH = np.zeros((12, 6))
WRENCH[:9, 3:] = CROSS
WRENCH[9:, :3] = np.eye(3)
WRENCH.setflags(write=False)

# [vec(s ⊗ f); f] (12,) = (AT_POINT @ [s; 1]) * (FORCE @ f), for the force f at a point s
AT_POINT = np.zeros((12, 4))
AT_POINT[np.arange(9), np.arange(9) // 3] = 1.0
AT_POINT[9:, 3] = 1.0
AT_POINT.setflags(write=False)
FORCE = np.vstack([np.eye(3)] * 4)
FORCE.setflags(write=False)

TINY = 1e-300

Index = NDArray[np.intp]
