"""A streamed orientation: read (a rotation matrix or a unit quaternion, checked) and moved
toward along the shortest rotation, at most a given angle per step."""

from __future__ import annotations

import math

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.geometry import matrix_to_quat, quat_to_matrix
from cpbc.errors import ParameterError

ORTHONORMAL = 1e-6  # how far from orthonormal a streamed rotation matrix may be
UNIT = 1e-3  # how far from 1 a streamed quaternion's norm may be (it is normalised)


def rotation_matrix(value: object, name: str) -> Array:
    """``value`` as a rotation matrix: a 3 × 3 rotation matrix (orthonormal to
    ``ORTHONORMAL``, determinant +1) or a unit quaternion (w, x, y, z) (norm 1 to
    ``UNIT``); ParameterError naming ``name`` otherwise."""
    what = (f"{name} must be a 3 × 3 rotation matrix or a unit quaternion (w, x, y, z) "
            "of finite numbers")
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ParameterError(name, f"{what}, got {value!r}") from None
    if not np.all(np.isfinite(a)):
        raise ParameterError(name, f"{what}, got {a.tolist()}")
    if a.shape == (4,):
        if not abs(float(np.linalg.norm(a)) - 1.0) <= UNIT:
            raise ParameterError(name, f"{what}, got a quaternion of norm "
                                       f"{np.linalg.norm(a):.6g}")
        return quat_to_matrix(a)
    if a.shape != (3, 3):
        raise ParameterError(name, f"{what}, got shape {a.shape}")
    if not (np.allclose(a.T @ a, np.eye(3), atol=ORTHONORMAL) and np.linalg.det(a) > 0):
        raise ParameterError(name, f"{what}, got a matrix that is not a rotation "
                                   f"({a.tolist()})")
    return a


def angle_between(start: Array, end: Array) -> float:
    """The angle [rad] of the shortest rotation from ``start`` to ``end``."""
    q = matrix_to_quat(start.T @ end)  # w ≥ 0: the shortest way
    return 2.0 * math.atan2(math.hypot(q[1], q[2], q[3]), q[0])


def turned_toward(start: Array, end: Array, share: float) -> Array:
    """The rotation ``share`` (0..1) of the way from ``start`` to ``end`` along the shortest
    rotation between them (``end`` itself at share 1)."""
    if share >= 1.0:
        return end.copy()
    q = matrix_to_quat(start.T @ end)
    sine = math.hypot(q[1], q[2], q[3])
    if sine == 0.0:
        return start.copy()
    half = share * math.atan2(sine, q[0])
    step = np.array([math.cos(half), *(math.sin(half) / sine * q[1:])])
    return start @ quat_to_matrix(step)
