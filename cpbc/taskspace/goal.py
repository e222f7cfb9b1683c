"""A frame's goal: a point of the frame at a world position, optionally its orientation (a
full rotation, or one tool axis along a world axis with the rotation about it free), and the
tolerance band within which the goal counts as reached."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cpbc.arrays import Array
from cpbc.model.frames import FrameKinematics


@dataclass(frozen=True)
class AxisGoal:
    """The tool axis ``tool`` (frame axes) along the world axis ``world``; both unit."""

    tool: Array
    world: Array


@dataclass(frozen=True)
class TaskError:
    """The distance from a frame to its goal.

    Attributes:
        position: ‖p − p_d‖ [m].
        angle: the rotation angle of R_dᵀR, or the angle between the tool axis and its
            world axis [rad]; 0 without an orientation goal.
    """

    position: float
    angle: float

    def within(self, position: float, angle: float) -> bool:
        return self.position <= position and self.angle <= angle


@dataclass(frozen=True)
class FrameGoal:
    """A goal for one frame of the arm.

    Attributes:
        frame: the frame id; ``frame_name`` its name.
        position: p_d, world [m], of the point ``offset`` (frame axes, None: the origin).
        rotation: R_d (3 × 3) or an :class:`AxisGoal`, or None (position only).
        tolerance: (position m, angle rad), the band of ``reached``.
    """

    frame: int
    frame_name: str
    position: Array
    offset: Array | None = None
    rotation: Array | AxisGoal | None = None
    tolerance: tuple[float, float] = (0.002, 0.02)

    def point(self, kin: FrameKinematics) -> Array:
        """The goal's point of the frame, world [m]."""
        return kin.point(self.offset)[0]

    def error(self, kin: FrameKinematics) -> TaskError:
        """The task error of the frame at a state."""
        distance = float(np.linalg.norm(self.point(kin) - self.position))
        return TaskError(distance, self.angle(kin.rotation))

    def angle(self, rotation: Array) -> float:
        """The orientation error of R [rad]."""
        if self.rotation is None:
            return 0.0
        if isinstance(self.rotation, AxisGoal):
            c = float(self.rotation.world @ (rotation @ self.rotation.tool))
        else:
            c = 0.5 * (float(np.trace(self.rotation.T @ rotation)) - 1.0)
        return math.acos(min(1.0, max(-1.0, c)))

    def reached(self, error: TaskError) -> bool:
        return error.within(*self.tolerance)
