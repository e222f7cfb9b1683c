"""What a policy's action means: each kind reads an action in the normalised box [-1, 1]^k
and streams one target to the tracker (cpbc.reference.tracker), which moves the law's applied
target toward it at the governor's pace. The deltas are taken from the frame's (or the
joints') measured state when the action arrives, so a policy that keeps pushing into an
obstacle asks for at most one step past where the arm is."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.geometry import quat_to_matrix
from cpbc.reference.tracker import ReferenceTracker


@dataclass(frozen=True)
class Measured:
    """The arm when an action arrives: its joints x (controller coordinates) and the
    tracked frame's point p [m] and rotation R in the world."""

    joints: Array
    position: Array
    rotation: Array


class ActionKind(Protocol):
    """An action kind: ``size`` numbers in [-1, 1], what they mean (``units``), and the
    target they stream (``send``)."""

    @property
    def size(self) -> int: ...

    @property
    def units(self) -> str: ...

    def send(self, tracker: ReferenceTracker, action: Array, now: Measured) -> None: ...


@dataclass(frozen=True)
class PoseDelta:
    """(Δp, ω): the frame's point moved by ``max_step`` · a[:3] [m] and turned by the
    rotation vector ``max_turn`` · a[3:] [rad] (world axes) from its measured pose
    (``set_pose``)."""

    max_step: float
    max_turn: float
    size: int = 6

    @property
    def units(self) -> str:
        return (f"a[:3] × {self.max_step} m along the world axes, a[3:] × {self.max_turn} rad "
                "as a rotation vector in the world, from the frame's measured pose")

    def send(self, tracker: ReferenceTracker, action: Array, now: Measured) -> None:
        turn = rotation_vector_matrix(self.max_turn * action[3:])
        tracker.set_pose(now.position + self.max_step * action[:3], turn @ now.rotation)


@dataclass(frozen=True)
class PositionDelta:
    """Δp: the frame's point moved by ``max_step`` · a [m] from its measured position
    (``set_target``)."""

    max_step: float
    size: int = 3

    @property
    def units(self) -> str:
        return f"a × {self.max_step} m along the world axes, from the frame's measured point"

    def send(self, tracker: ReferenceTracker, action: Array, now: Measured) -> None:
        tracker.set_target(now.position + self.max_step * action)


@dataclass(frozen=True)
class JointTarget:
    """x_r: the joints' target, a mapped linearly from [-1, 1] onto [``lower``, ``upper``]
    (controller coordinates, rad or m) (``set_joint_target``)."""

    lower: Array
    upper: Array

    @property
    def size(self) -> int:
        return len(self.lower)

    @property
    def units(self) -> str:
        return ("a mapped linearly onto the joints' ranges, -1 at the lower and 1 at the "
                "upper limit [rad or m]")

    def send(self, tracker: ReferenceTracker, action: Array, now: Measured) -> None:
        tracker.set_joint_target(self.lower + 0.5 * (action + 1.0) * (self.upper - self.lower))


@dataclass(frozen=True)
class JointDelta:
    """Δx: the joints' target ``max_step`` · a [rad or m] from their measured positions
    (``set_joint_target``)."""

    max_step: float
    size: int

    @property
    def units(self) -> str:
        return f"a × {self.max_step} rad (or m) per joint, from the measured joints"

    def send(self, tracker: ReferenceTracker, action: Array, now: Measured) -> None:
        tracker.set_joint_target(now.joints + self.max_step * action)


def rotation_vector_matrix(omega: Array) -> Array:
    """The rotation by the rotation vector ω (its axis, |ω| rad) as a matrix."""
    angle = math.hypot(*omega)
    if angle == 0.0:
        return np.eye(3)
    half = 0.5 * angle
    return quat_to_matrix(np.array([math.cos(half), *(math.sin(half) / angle * omega)]))
