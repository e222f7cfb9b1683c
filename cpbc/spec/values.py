"""Numbers of a scenario checked against its robot: vectors of the right length, and the
limits the robot's model declares. Errors are ScenarioErrors naming the field."""

from __future__ import annotations

import numpy as np

from cpbc.arrays import Array
from cpbc.errors import ScenarioError
from cpbc.model.robot_model import RobotModel


def vector(value: list[float] | None, n: int, field: str, default: float | None = None) -> Array:
    """``value`` as n numbers (``default`` everywhere when it is None and a default is given)."""
    if value is None and default is not None:
        return np.full(n, default)
    a = np.asarray(value, dtype=float)
    if a.shape != (n,):
        raise ScenarioError(field, f"needs {n} entries (one per coordinate), got {a.size}")
    return a


def model_limits(
    model: RobotModel, kind: str, field: str, joints: list[int] | None = None
) -> tuple[Array, Array]:
    """Limits the robot's model declares: ``position`` (lower, upper), ``velocity`` or
    ``effort`` (−limit, limit), in joint coordinates, of every joint (or of ``joints``).
    ScenarioError if one of them has none or the controller does not use joint
    coordinates."""
    if not model.coordinates.is_identity:
        raise ScenarioError(field, "'from_model' limits need robot.coordinates: joint")
    pm = model.model
    if kind == "position":
        lo = np.array(pm.lowerPositionLimit, dtype=float)
        hi = np.array(pm.upperPositionLimit, dtype=float)
    else:
        hi = np.array(pm.velocityLimit if kind == "velocity" else pm.effortLimit, dtype=float)
        lo = -hi
    chosen = range(model.n) if joints is None else joints
    bad = [model.joint_names[i] for i in chosen
           if not (np.isfinite(lo[i]) and np.isfinite(hi[i]) and lo[i] < hi[i])]
    if bad:
        others = [model.joint_names[i] for i in chosen if model.joint_names[i] not in bad]
        hint = f", or list only the joints that have one ('joints': {others})" if others else ""
        raise ScenarioError(field, f"the model has no {kind} limit for joints {bad} "
                            f"(continuous or undeclared): give values{hint}")
    return lo, hi
