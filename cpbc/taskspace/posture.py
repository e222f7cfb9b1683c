"""Continuous joints and the set points a law pulls toward.

A continuous joint (a URDF ``continuous`` joint: the Kinova Jaco2's joints 1, 4 and 6, the
PR2's forearm and wrist rolls) has no stop: q and q + 2πk are one configuration, and the
dynamics, the frames and every constraint but a position limit on that joint are 2π-periodic
in it. A joint spring ½K(q − q_n)² is not: from a start wound by a full turn it pulls the arm
back through the turn. So the set point a run's law takes (the goal's posture x_n, or a joint
``target:``) is the equivalent one nearest that run's start,

    x_n ← x_n + 2π round((x₀ − x_n)/2π)   on the continuous joints,

and the arm moves by at most π on each of them to reach it.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.errors import ConstraintViolation
from cpbc.model.robot_model import RobotModel

TURN = 2.0 * np.pi


def continuous_mask(model: RobotModel, continuous: Sequence[str]) -> Array | None:
    """Which coordinates are continuous joints, (n,) bool; None when none is (or the
    controller's coordinates mix joints, where a turn of one is not a turn of a coordinate)."""
    if not continuous or not model.coordinates.is_identity:
        return None
    mask = np.array([name in continuous for name in model.joint_names])
    return mask if mask.any() else None


def nearest_turns(x: Array, start: Array, periodic: Array | None) -> Array:
    """The set point ``x`` turned by whole turns on the ``periodic`` coordinates to the
    equivalent nearest ``start`` (module docstring); ``x`` itself where none is."""
    x = np.asarray(x, dtype=float)
    if periodic is None:
        return x
    turns = np.where(periodic, np.round((np.asarray(start, dtype=float) - x) / TURN), 0.0)
    return x + TURN * turns


def admissible_turns(x: Array, start: Array, periodic: Array | None,
                     constraints: ConstraintSet) -> Array:
    """:func:`nearest_turns`, unless that equivalent lies outside the configuration
    constraints (a position limit the user put on a continuous joint): then ``x``."""
    turned = nearest_turns(x, start, periodic)
    if np.array_equal(turned, x) or constraints.empty:
        return turned
    try:
        margins = constraints.configuration_margins(turned)
    except ConstraintViolation:
        return np.asarray(x, dtype=float)
    return turned if np.all(margins > 0) else np.asarray(x, dtype=float)
